"""The competition's Python environment (``{competition_python}``): a real second virtual
environment made from the package index, recorded, reused, made by one command at a time, never
used half-made; and ``eval``/``sweep`` ``--cmd`` templates that name it."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import signal
import socket
import subprocess
import sys

import pytest
from clirun import run_cli
from paths import TESTS

from arenabench.eval.runs.competition_env import (
    COMPETITION_PINS,
    COMPETITION_PLACEHOLDER,
    RECORD_FILE,
    competition_python,
    env_folder,
    substitute_competition_python,
)

PIPELINES = TESTS / "pipelines"
LEGACY = PIPELINES / "style_legacy_aruco.py"  # cv2.aruco.detectMarkers: OpenCV 4.x only


@pytest.fixture()
def offline(monkeypatch):
    """No package index: pip's index is a closed local port, no other source of wheels."""
    closed = socket.socket()  # bound, never listening: connections are refused
    closed.bind(("127.0.0.1", 0))
    for key, value in {"PIP_INDEX_URL": f"http://127.0.0.1:{closed.getsockname()[1]}/simple/",
                       "PIP_EXTRA_INDEX_URL": "", "PIP_FIND_LINKS": "", "PIP_RETRIES": "0",
                       "PIP_CONFIG_FILE": os.devnull}.items():
        monkeypatch.setenv(key, value)
    yield
    closed.close()


def test_substitute_replaces_the_placeholder_argument_by_argument():
    cmd = substitute_competition_python(f"{COMPETITION_PLACEHOLDER} 'my map.py' --image {{image}}",
                                        "/a b/bin/python")
    assert cmd == "'/a b/bin/python' 'my map.py' --image '{image}'"
    assert substitute_competition_python("python3 map.py", "/x") == "python3 map.py"


@pytest.mark.integration
def test_the_environment_holds_the_pins_and_is_reused(competition_cache, capfd):
    folder = env_folder(competition_cache)
    record = json.loads((folder / RECORD_FILE).read_text())
    assert record["requirements"] == [p.requirement for p in COMPETITION_PINS]
    for pin in COMPETITION_PINS:
        assert pin.matches(record["versions"][pin.module])
    probe = subprocess.run([str(folder / "bin" / "python"), "-c",
                            "import numpy, cv2; print(numpy.__version__, cv2.__version__, "
                            "hasattr(cv2.aruco, 'detectMarkers'))"],
                           capture_output=True, text=True, check=True)
    assert probe.stdout.split() == [record["versions"]["numpy"], record["versions"]["cv2"],
                                    "True"]
    assert sorted(p.name for p in folder.parent.iterdir()) == [folder.name, folder.name + ".lock"]
    again = competition_python(cache=competition_cache, prog="again")
    assert again.source == "competition" and not again.made
    assert again.executable == str(folder / "bin" / "python")
    assert capfd.readouterr().err == ""  # reused: nothing made, nothing said


@pytest.mark.integration
def test_a_half_made_environment_is_never_used(tmp_path, offline, capfd):
    """A folder without its record (a build killed before the rename could not leave one, but
    a hand-made or damaged one can) and a killed build's temporary folder: neither is used, both
    are removed when the environment is made again."""
    folder = env_folder(tmp_path)
    (folder / "bin").mkdir(parents=True)
    os.symlink(sys.executable, folder / "bin" / "python")
    stale = folder.parent / f".{folder.name}.tmp-killed"
    stale.mkdir()
    got = competition_python(cache=tmp_path, progress=False, prog="t")
    assert got.source == "fallback" and got.executable == sys.executable
    assert "No matching distribution" in got.problem
    assert [p.name for p in folder.parent.iterdir()] == [folder.name + ".lock"]
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "cannot be made" in err[1]


@pytest.mark.integration
def test_a_second_command_waits_for_the_one_making_it_and_reuses_its_work(
        competition_cache, tmp_path, offline):
    """While one command holds the build lock, another waits (and says so in one line), then
    uses what the first made: it makes nothing itself (offline, it could not)."""
    cache = tmp_path / "cache"
    folder = env_folder(cache)
    folder.parent.mkdir(parents=True)
    lock = os.open(folder.with_name(folder.name + ".lock"), os.O_RDWR | os.O_CREAT, 0o644)
    fcntl.flock(lock, fcntl.LOCK_EX)
    code = ("from arenabench.eval.runs.competition_env import competition_python\n"
            f"i = competition_python(cache={str(cache)!r}, prog='second')\n"
            "print('RESULT', i.source, i.made, i.executable, flush=True)\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        first = proc.stderr.readline()  # waits for the event: it found the lock held
        assert first.startswith("second: waiting for another command making"), first
        # "the first command" finishes: its environment appears whole, by a rename
        tmp = folder.with_name(f".{folder.name}.tmp-first")
        shutil.copytree(env_folder(competition_cache), tmp, symlinks=True,
                        copy_function=os.link)
        os.rename(tmp, folder)
    finally:
        fcntl.flock(lock, fcntl.LOCK_UN)
        os.close(lock)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert out.split() == ["RESULT", "competition", "False", str(folder / "bin" / "python")]
    assert err == ""  # nothing made, no warning


@pytest.mark.integration
@pytest.mark.parametrize("when", ["starting", "installing"])
def test_a_stopped_build_leaves_nothing_half_made(tmp_path, when):
    """SIGINT while the environment is being made (as it starts, or while pip installs): the
    command stops, every process of the build is ended and its temporary folder removed; no
    environment folder appears."""
    cache = tmp_path / "cache"
    folder = env_folder(cache)
    code = ("from arenabench.interrupts import Interrupted, stop_on_signals\n"
            "from arenabench.eval.runs.competition_env import competition_python\n"
            "with stop_on_signals():\n"
            "    try:\n"
            f"        competition_python(cache={str(cache)!r}, prog='stopped')\n"
            "    except Interrupted:\n"
            "        print('STOPPED', flush=True)\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stderr.readline().startswith("stopped: making the competition's")
    if when == "installing":
        for line in proc.stderr:  # pip's first step line: venv and ensurepip are done
            if line.startswith("  pip: "):
                break
        else:
            pytest.fail("pip showed no step")
    proc.send_signal(signal.SIGINT)
    out, _ = proc.communicate(timeout=120)
    assert out.strip() == "STOPPED"
    assert not _processes_naming(str(cache))
    assert [p.name for p in folder.parent.iterdir()] == [folder.name + ".lock"]


#: Points of the build ``check`` is stopped at: its first line (the venv starts), pip's first
#: step line (venv and ensurepip done) and pip installing into the temporary folder.
BUILD_POINTS = {"starting": "arenabench check: making the competition's",
                "collecting": "  pip: Collecting", "installing": "  pip: Installing collected"}


@pytest.mark.integration
@pytest.mark.parametrize("point", list(BUILD_POINTS))
def test_ctrl_c_to_check_while_it_makes_the_environment_stops_it(tmp_path, point):
    """A Ctrl-C (SIGINT to the process group) while ``check`` makes the environment: exit 130
    with its one line, no process of the build left, the cache holding only the lock file."""
    cache = tmp_path / "cache"
    script = tmp_path / "map.py"
    script.write_text("import sys\nsys.exit(3)\n")
    argv = [sys.executable, "-m", "arenabench", "check", str(script), "--count", "1",
            "--out", str(tmp_path / "report")]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "ARENABENCH_CACHE_DIR": str(cache),
                                 "PYTHONUNBUFFERED": "1"}, start_new_session=True)
    said = []
    try:
        for line in proc.stderr:  # the event: the build reached the point
            said.append(line)
            if line.startswith(BUILD_POINTS[point]):
                break
        else:
            pytest.fail(f"the build never reached {point!r}: {''.join(said)}")
        os.killpg(proc.pid, signal.SIGINT)
        rest = proc.stderr.read()
        proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, "".join(said) + rest
    assert "interrupted" in rest.strip().splitlines()[-1], rest
    assert not _processes_naming(str(cache))
    folder = env_folder(cache)
    assert [p.name for p in folder.parent.iterdir()] == [folder.name + ".lock"]


@pytest.mark.integration
def test_eval_and_sweep_run_competition_python_commands(competition_cache, tmp_path):
    env = {"ARENABENCH_CACHE_DIR": str(competition_cache)}
    data = tmp_path / "set"
    gen = run_cli("generate", "--count", "2", "--seed", "0", "--out", str(data), "--workers",
                  "1", "--no-progress")
    assert gen.returncode == 0, gen.stderr
    cmd = f"{COMPETITION_PLACEHOLDER} {LEGACY} --image {{image}}"
    out = tmp_path / "eval"
    proc = run_cli("eval", str(data), "--cmd", cmd, "--out", str(out), "--no-progress",
                   "--phase-check", "off", "--fail-under", "pass_rate=1", env=env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    python = env_folder(competition_cache) / "bin" / "python"
    assert f"{COMPETITION_PLACEHOLDER} is {python}" in proc.stderr
    report = json.loads((out / "report.json").read_text())
    assert report["pipeline"] == cmd  # the name the user gave
    assert report["interpreter"]["source"] == "competition"
    assert report["interpreter"]["executable"] == str(python)
    sweep_out = tmp_path / "sweep"
    proc = run_cli("sweep", "--vary", "degrade.noise_sigma=0", "--per-point", "2", "--cmd", cmd,
                   "--out", str(sweep_out), "--workers", "1", "--no-progress", "--no-plots",
                   "--phase-check", "off", env=env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = [json.loads(x) for x in (sweep_out / "results.jsonl").read_text().splitlines()]
    assert len(rows) == 2 and all(r["pass"] for r in rows), rows


def _processes_naming(text: str) -> list[str]:
    """The command lines of live processes that name ``text``."""
    found = []
    for entry in os.scandir("/proc"):
        if entry.name.isdigit():
            try:
                with open(f"/proc/{entry.name}/cmdline", "rb") as fh:
                    cmdline = fh.read().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if text in cmdline:
                found.append(cmdline)
    return found
