"""The warm server's warm-up (eval/warm_up.py) in a fresh interpreter, and what a run sees of
it: the libraries exercised on synthetic data only, OpenCV's threads and every random
generator left as they were, a submission's own module of a preloaded name its own; and the
server single-threaded when it says it is ready (the libraries' spinning threads stopped)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from marks import integration_but

from arenabench.eval.runs import CommandPipeline
from arenabench.eval.runs.limits import RunSettings
from arenabench.eval.runs.sandbox import bwrap_problem
from arenabench.eval.runs.warm_client import WARM_UP_SOURCE

PROBE = r"""
import json, random, sys
import argparse, cv2, numpy
import warm_up  # the helper script's folder is on PYTHONPATH

def threads():
    for line in open("/proc/self/status"):
        if line.startswith("Threads:"):
            return int(line.split()[1])

def draws(seed):
    random.seed(seed)
    numpy.random.seed(seed)
    cv2.setRNGSeed(seed)
    return lambda: [random.random(), float(numpy.random.random()),
                    cv2.randu(numpy.zeros(4, numpy.float32), 0, 1).tolist()]

before = (threads(), cv2.getNumThreads())
expected = draws(7)()
draw = draws(7)
done = warm_up.warm_up()
print(json.dumps({"done": done, "threads": [before[0], threads()],
                  "num_threads": [before[1], cv2.getNumThreads()],
                  "draws_same": draw() == expected,
                  "partial": warm_up.warm_up({"numpy": numpy})}))
"""


def test_warm_up_exercises_the_libraries_and_leaves_threads_and_generators_alone():
    env = {**os.environ, "PYTHONPATH": str(WARM_UP_SOURCE.parent)}
    out = subprocess.run([sys.executable, "-c", PROBE], env=env,
                         capture_output=True, text=True, check=True, timeout=120)
    seen = json.loads(out.stdout.strip().splitlines()[-1])
    assert seen["done"] == ["argparse", "numpy", "cv2"]
    assert seen["threads"][1] == seen["threads"][0], "the warm-up started threads"
    assert seen["num_threads"][1] == seen["num_threads"][0]
    assert seen["draws_same"], "the warm-up drew from a random generator"
    assert seen["partial"] == ["numpy"]  # only what the server has imported
    assert out.stderr == ""  # argparse's error path writes to a captured stream


SHADOW = """
import argparse
import cv2

parser = argparse.ArgumentParser()
parser.add_argument("--image", required=True)
parser.parse_args()
print(cv2.WHOSE)
with open("obstacles.txt", "w") as fh:
    fh.write("Aruco ID: []\\nObstacles: 0\\nArea: 0\\n")
"""


@pytest.mark.parametrize("warm", [True, False])
def test_a_submissions_own_module_of_a_preloaded_name_is_its_own(tmp_path, warm):
    sub = tmp_path / "team"
    sub.mkdir()
    (sub / "map.py").write_text(SHADOW)
    (sub / "cv2.py").write_text("WHOSE = 'the team'\n")
    image = tmp_path / "img.png"
    image.write_bytes(b"not read")
    with CommandPipeline(f"{sys.executable} {sub / 'map.py'} --image {{image}}",
                         settings=RunSettings(sandbox="none", warm=warm)) as pipe:
        preds = [pipe.run(Path(image)) for _ in range(2)]
    assert [p.status for p in preds] == ["ok", "ok"], preds[0].stderr
    assert [p.stdout.strip() for p in preds] == ["the team", "the team"]


def _threads_of_server(home):
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            argv = (entry / "cmdline").read_bytes().split(b"\0")
            status = (entry / "status").read_text()
        except OSError:
            continue
        if argv[1:2] == [b"-c"] and home.encode() in argv:  # not the keeper (python -I -S)
            return int(status.split("Threads:")[1].split()[0])
    raise AssertionError(f"no server process with {home} on its command line")


def test_the_server_is_single_threaded_when_ready(tmp_path):
    """numpy's and OpenCV's OpenBLAS start spinning threads at import; the server stops them
    (as each run's fork would) before it says it is ready, rather than let them spin."""
    script = tmp_path / "map.py"
    script.write_text("import cv2\nimport numpy\n")
    image = tmp_path / "img.png"
    image.write_bytes(b"not read")
    with CommandPipeline(f"{sys.executable} {script} --image {{image}}",
                         settings=RunSettings(sandbox="none")) as pipe:
        server = pipe.context.servers.server_for(pipe, image)
        assert server is not None
        threads = _threads_of_server(server.home)  # no run forked yet
    assert threads == 1


def _submission(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root / "map.py"


def test_what_the_submissions_own_modules_import_is_found_without_running_them(tmp_path):
    """The script's imports and, through the submission's modules it imports (plain, package,
    relative, a cycle), theirs: read with ast, never run."""
    from arenabench.eval.runs.warm_server import _script_imports

    ran = tmp_path / "ran"
    boom = f"open({str(ran)!r}, 'w').close()\n"
    script = _submission(tmp_path / "team", {
        "map.py": "import sys\nimport helper\nfrom pkg import sub\n" + boom,
        "helper.py": "import argparse\nimport map\n" + boom,  # a cycle back to the script
        "pkg/__init__.py": boom,
        "pkg/sub.py": "from .inner import thing\n\ndef later():\n    import json\n" + boom,
        "pkg/inner.py": "import shutil\nthing = 1\n" + boom,
    })
    (tmp_path / "outside.py").write_text("import zipfile\n" + boom)  # beside the submission
    (script.parent / "pkg" / "inner.py").write_text(
        "import shutil\nfrom ... import outside\nthing = 1\n" + boom)
    names = _script_imports(str(script), [str(script.parent)])
    assert names[:3] == ["sys", "helper", "pkg"]
    assert {"argparse", "json", "shutil"} <= set(names) and "inner" not in names
    assert "zipfile" not in names, "a file outside the submission's folder was read"
    assert not ran.exists(), "a submission's module was run"


def test_the_search_through_a_submissions_modules_is_bounded(tmp_path, monkeypatch):
    from arenabench.eval.runs import warm_server

    n = warm_server.LOCAL_MODULES_MAX + 5
    files = {"map.py": "import m0\n"}
    files.update({f"m{i}.py": f"import m{i + 1}\nimport mod_of_{i}\n" for i in range(n)})
    script = _submission(tmp_path / "team", files)
    names = warm_server._script_imports(str(script), [str(script.parent)])
    read = [int(x[len("mod_of_"):]) for x in names if x.startswith("mod_of_")]
    assert read == list(range(warm_server.LOCAL_MODULES_MAX - 1))  # the script is one file
    monkeypatch.setattr(warm_server, "IMPORTED_NAMES_MAX", 7)
    assert warm_server._script_imports(str(script), [str(script.parent)]) == [
        "m0", "m1", "mod_of_0", "m2", "mod_of_1", "m3", "mod_of_2"]
    monkeypatch.setattr(warm_server, "LOCAL_MODULE_BYTES_MAX", 5)  # "import m0\n" is 10
    assert warm_server._script_imports(str(script), [str(script.parent)]) == []


HELPED = """
import sys
seen = "argparse" in sys.modules, "helper" in sys.modules
import helper
print(*seen)
with open("obstacles.txt", "w") as fh:
    fh.write("Aruco ID: []\\nObstacles: 0\\nArea: 0\\n")
"""


@pytest.mark.parametrize("sandbox", integration_but([pytest.param("bwrap", marks=pytest.mark.skipif(
    bwrap_problem() is not None, reason=str(bwrap_problem()))), "none"], "bwrap"))
@pytest.mark.parametrize("warm", integration_but([True, False], True))
def test_a_helper_modules_imports_are_preloaded_and_the_helper_runs_in_each_run(
        tmp_path, warm, sandbox):
    """What a submission's own module imports (argparse) is in the server; the module itself
    is imported by each run, as in a cold run."""
    script = _submission(tmp_path / "team", {
        "map.py": HELPED,
        "helper.py": "import argparse\n",
    })
    image = tmp_path / "img.png"
    image.write_bytes(b"not read")
    with CommandPipeline(f"{sys.executable} {script} --image {{image}}",
                         settings=RunSettings(sandbox=sandbox, warm=warm)) as pipe:
        preds = [pipe.run(Path(image)) for _ in range(2)]
    assert [p.status for p in preds] == ["ok", "ok"], preds[0].stderr
    assert [p.stdout.split() for p in preds] == [[str(warm), "False"]] * 2
