"""Hostile inputs given to ``arenabench``: the answer is a clean one-line error (exit 2) or a
correct failure verdict, never a traceback, a hang or a wrong success. Commands run in the test
process (:func:`clirun.run_cli`, output captured at the file descriptors); the ones that could
block (FIFOs), write to devices, or run pipelines that end or hang their process run as a real
``arenabench`` subprocess with a timeout.

Covers: non-finite / negative / fractional answers (bad_output), invalid GT values (dataset
error naming file and field), JSON output that stays valid, ``--out`` paths that cannot be
written, absurd sizes, ``detect`` on a FIFO and with ``--output -`` or a device, manifest
SHA-256 verification (``--no-verify``), and the lock on ``generate``'s output folder.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import stat
import subprocess
import sys
from pathlib import Path

import liar
import pytest
import toy_arena
from clirun import run_cli
from marks import integration_but
from paths import ROOT, TESTS

from arenabench.fileio import LOCK_FILE, dumps_json, dumps_json_line, lock_folder

HERE = TESTS
PIPES = HERE / "pipelines"
EXAMPLE = HERE / "data" / "task1c_image.jpg"

TIMEOUT_S = 240


def _pythonpath() -> str:
    return os.pathsep.join([str(PIPES), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)


def run(*argv: str, cwd: Path | None = None):
    """``arenabench ARGV`` in this process; the test pipelines are importable by its children."""
    return run_cli(*argv, cwd=cwd, env={"PYTHONPATH": _pythonpath()})


def run_process(*argv: str, cwd: Path | None = None, timeout: float = TIMEOUT_S):
    """``arenabench ARGV`` in a fresh interpreter; the test pipelines are importable."""
    env = {**os.environ, "PYTHONPATH": _pythonpath()}
    return subprocess.run([sys.executable, "-m", "arenabench", *argv], capture_output=True,
                          text=True, timeout=timeout, cwd=cwd, env=env)


def assert_clean_error(proc, *needles: str, prog: str | None = None) -> str:
    """Exit 2, one line on stderr (``arenabench <prog>: error: ...``), no traceback."""
    err = proc.stderr.strip()
    assert "Traceback" not in proc.stderr, proc.stderr
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert len(err.splitlines()) == 1, err
    if prog:
        assert err.startswith(f"arenabench {prog}: error: "), err
    for needle in needles:
        assert needle in err, (needle, err)
    return err


def strict_json(text: str):
    """Parse JSON refusing NaN and infinities (what browsers and jq do)."""
    def refuse(token):
        raise ValueError(f"non-standard JSON constant {token}")

    return json.loads(text, parse_constant=refuse)


def rehash(root: Path) -> None:
    """Rewrite the manifest's SHA-256 values after a test edited files on purpose."""
    lines = []
    for line in (root / "manifest.jsonl").read_text().splitlines():
        entry = json.loads(line)
        for key, field in (("image", "image_sha256"), ("gt", "gt_sha256")):
            entry[field] = hashlib.sha256((root / entry[key]).read_bytes()).hexdigest()
        lines.append(json.dumps(entry))
    (root / "manifest.jsonl").write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("hostile") / "toy", n=3, seed=2)


# ------------------------------------------------------------------------- wrong scores


@pytest.mark.parametrize("name", integration_but(sorted(liar.ANSWERS), "nan_area"))
def test_impossible_answer_of_a_callable_is_bad_output(toy, tmp_path, name):
    proc = run("eval", str(toy), "--pipeline", f"liar:{name}", "--out", str(tmp_path),
               "--no-progress", "--formats", "json", "--fail-under", "pass_rate=0.01")
    assert "Traceback" not in proc.stderr, proc.stderr
    assert proc.returncode == 1, proc.stderr  # the threshold is missed: nothing passed
    report = strict_json((tmp_path / "report.json").read_text())
    assert report["summary"]["n_passed"] == 0
    assert report["summary"]["failures"]["bad_output"] == 3
    for image in report["images"]:
        assert image["category"] == "bad_output"
        assert image["pred"]["area"] is None or math.isfinite(image["pred"]["area"])


@pytest.mark.integration  # a pool of 2 processes per case, the endless ones wait out a timeout
@pytest.mark.parametrize("executor", ["thread", "process"])
@pytest.mark.parametrize(
    ("name", "category", "message"),
    [
        ("sys_exit", "crash", "the pipeline called sys.exit(0)"),
        ("os_exit", "crash", "the pipeline ended its process (exit status 0"),
        ("keyboard_interrupt", "crash", "the pipeline raised KeyboardInterrupt"),
        ("endless", "timeout", "timed out after 1.5 s (its process killed)"),
    ],
)
def test_a_callable_that_exits_or_hangs_fails_its_images_only(toy, tmp_path, executor, name,
                                                               category, message):
    proc = run_process("eval", str(toy), "--pipeline", f"hostile_callables:{name}",
                       "--executor", executor, "--timeout", "1.5", "--workers", "2",
                       "--out", str(tmp_path / "o"), "--formats", "json", "--no-progress")
    assert "Traceback" not in proc.stderr, proc.stderr
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith(f"hostile_callables:{name}: pass rate 0.0 % (0/3")
    report = strict_json((tmp_path / "o" / "report.json").read_text())
    assert [i["category"] for i in report["images"]] == [category] * 3
    assert all(i["message"].startswith(message) for i in report["images"]), report["images"]


@pytest.mark.parametrize(
    ("args", "needle"),
    integration_but([
        (("--output", "json", "--json", '{"count": 1, "area": NaN}'), "area is not a finite"),
        (("--output", "json", "--json", '{"count": 1, "area": 1e400}'), "area is not a finite"),
        (("--output", "json", "--json", '{"count": true, "area": 5}'), "count is not an integer"),
        (("--output", "json", "--json", '{"count": 1.5, "area": 5}'), "count is not an integer"),
        (("--output", "json", "--json", '{"count": -2, "area": 5}'), "count is negative"),
        (("--obstacles", "Obstacles: 1\\nArea: nan"), "area is not a finite number"),
        (("--obstacles", "Obstacles: 1\\nTotal Area: -inf"), "area is not a finite number"),
        (("--obstacles", "Obstacles: 1\\nArea: -3"), "area is negative"),
        (("--obstacles", "Obstacles: 1e400\\nArea: 3"), "count is not a finite number"),
        (("--obstacles", "Obstacles: 9007199254740992\\nArea: 3"),
         "obstacle count is larger than 1000"),
        (("--obstacles", "Obstacles: 6000\\nArea: 3"), "obstacle count is larger than 1000"),
        (("--obstacles", "Aruco ID: [80, -1]\\nObstacles: 1\\nArea: 3"), "marker id is negative"),
        (("--output", "json", "--json", '{"count": 6000, "area": 5}'),
         "count is larger than 1000"),
        (("--output", "json", "--json", '{"count": 1, "area": 5, "marker_ids": [99999]}'),
         "marker id is larger than"),
    ], first=1),
)
def test_impossible_answer_of_a_command_is_bad_output(toy, tmp_path, args, needle):
    output = ("--output", "json") if args[0] == "--output" else ()
    from arenabench.cmdtemplate import escape

    script_args = " ".join(f"'{escape(a)}'" for a in args[len(output):])  # braces doubled
    cmd = f"{{python}} {PIPES / 'liar.py'} --image {{image}} {script_args}"
    proc = run("eval", str(toy), "--cmd", cmd, *output, "--out", str(tmp_path),
               "--no-progress", "--formats", "json", "--fail-under", "pass_rate=0.01")
    assert "Traceback" not in proc.stderr, proc.stderr
    assert proc.returncode == 1, proc.stderr
    report = strict_json((tmp_path / "report.json").read_text())
    assert [i["category"] for i in report["images"]] == ["bad_output"] * 3
    assert needle in report["images"][0]["message"], report["images"][0]["message"]


def test_score_never_passes_a_non_finite_value():
    from arenabench.eval.scoring.metrics import score_image
    from arenabench.eval.scoring.results import Prediction, Truth

    truth = Truth(count=1, area=100.0, marker_ids=())
    for count, area in ((1, float("nan")), (1, float("inf")), (1, -100.0), (1.5, 100.0),
                        (float("nan"), 100.0), (True, 100.0)):
        score = score_image(truth, Prediction(status="ok", count=count, area=area),
                            tolerance=math.inf)
        assert not score.passed and score.category == "bad_output", (count, area, score)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda g: g["area"].update(visible_px=float("nan")),
         "area.visible_px: nan is not a finite number"),
        (lambda g: g["area"].update(footprint_px=float("-inf")),
         "area.footprint_px: -inf is not a finite number"),
        (lambda g: g["area"].update(visible_px=-1.0),
         "area.visible_px: -1.0 is less than the minimum of 0"),
        (lambda g: g.update(count=True), "count: True is not of type 'integer'"),
        (lambda g: g.update(count=1.5), "count: 1.5 is not of type 'integer'"),
        (lambda g: g.update(count=float("inf")), "count: inf is not a finite number"),
        (lambda g: g.update(count=-1), "count: -1 is less than the minimum of 0"),
        (lambda g: g["markers"][0].update(id="80"), "markers[0].id: '80' is not of type"),
        (lambda g: g.update(schema="arenabench.gt/0"), "schema: 'arenabench.gt/1' was expected"),
        # numbers that reports bin or plot: at most what a scene or a frame can hold
        (lambda g: g.update(count=10**30),
         f"count: {10**30} is greater than the maximum of 1000"),
        (lambda g: g.update(components=10**30),
         f"components: {10**30} is greater than the maximum of 1000"),
        (lambda g: g["area"].update(visible_px=1e308),
         "area.visible_px: 1e+308 is greater than the maximum of 134217728"),
        (lambda g: g["area"].update(footprint_px=2e8),
         "area.footprint_px: 200000000.0 is greater than the maximum of 134217728"),
        (lambda g: g.update(image_size=[10**6, 1000]),
         "image_size[0]: 1000000 is greater than the maximum of 8192"),
        # junk marker ids
        (lambda g: g["markers"][0].update(id=-1), "markers[0].id: -1 is less than the minimum"),
        (lambda g: g["markers"][0].update(id=2**70),
         f"markers[0].id: {2**70} is greater than the maximum of 2319"),
        (lambda g: g["markers"][2].update(id=90.0), "markers[2].id: 90.0 is not an integer"),
        (lambda g: g["markers"][0].update(id=1e20), "markers[0].id: 1e+20 is "),
        (lambda g: g["markers"][3].update(id=g["markers"][1]["id"]),
         "markers[3].id: 85 repeats markers[1].id"),
    ],
)
def test_invalid_gt_value_is_a_dataset_error_naming_file_and_field(toy, tmp_path, edit,
                                                                   message):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(toy, bad)
    gt_file = bad / "gt" / "000001.json"
    gt = json.loads(gt_file.read_text())
    edit(gt)
    gt_file.write_text(json.dumps(gt))  # Python writes NaN / Infinity as a JSON extension
    rehash(bad)
    proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress")
    assert_clean_error(proc, f"gt/000001.json: {message}", prog="eval")


def _manifest_with(toy: Path, tmp_path: Path, key: str, value: str) -> Path:
    """A copy of ``toy`` whose second manifest entry has ``key`` = ``value``."""
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(toy, bad)
    manifest = bad / "manifest.jsonl"
    rows = [json.loads(line) for line in manifest.read_text().splitlines()]
    rows[1][key] = value
    manifest.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return bad


@pytest.mark.parametrize(
    ("key", "value", "needle"),
    [
        ("id", "a/b", "field 'id' 'a/b': "),
        ("id", "x" * 300, "field 'id' 'xxxxxxxx"),
        ("id", "", "field 'id' '': "),
        ("id", "-rf", "field 'id' '-rf': "),
        ("image", "images/000001\n.png", "field 'image' 'images/000001\\n.png': "),
        ("gt", "gt/000001.json\r", "field 'gt' 'gt/000001.json\\r': "),
    ],
)
@pytest.mark.parametrize("command", ["eval", "grade"])
def test_manifest_ids_and_paths_that_no_report_can_show_are_refused(toy, tmp_path, key, value,
                                                                    needle, command):
    bad = _manifest_with(toy, tmp_path, key, value)
    if command == "eval":
        proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress",
                   "--out", str(tmp_path / "out"))
    else:
        teams = tmp_path / "teams"
        (teams / "a").mkdir(parents=True)
        from procs_limit import GRADE_ARGS

        proc = run("grade", str(bad), str(teams), "--out", str(tmp_path / "out"),
                   "--allow-guessable-seed", *GRADE_ARGS)
    err = assert_clean_error(proc, f"{bad / 'manifest.jsonl'}:2: {needle}", prog=command)
    assert len(err) < 400, err  # a 300-character id is shortened
    assert not (tmp_path / "out").exists()


def test_gt_count_1e400_is_refused(toy, tmp_path):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(toy, bad)
    gt_file = bad / "gt" / "000002.json"
    text = gt_file.read_text()
    gt_file.write_text(text.replace('"count": ', '"count": 1e400, "was": ', 1))
    rehash(bad)
    proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress")
    assert_clean_error(proc, "gt/000002.json: count: inf is not a finite number", prog="eval")


def test_every_gt_the_generator_writes_validates():
    from arenabench.generator.commands.render import scene_gt_record
    from arenabench.generator.dataset.make import gt_record
    from arenabench.generator.model.sampler import sample_scene
    from arenabench.generator.model.scene import load_scene
    from arenabench.generator.parameters.presets import preset_names
    from arenabench.schemas import GT_SCHEMA, gt_problem, gt_schema

    assert gt_schema()["properties"]["schema"]["const"] == GT_SCHEMA
    checked = 0
    for preset in preset_names():
        for index in range(8):
            s = sample_scene(preset, seed=3, index=index)
            gt = gt_record(s.scene, sid=f"{index:06d}", preset=preset, seed=3, index=index,
                           params=s.params)
            # as written to disk: canonical JSON, read back
            assert gt_problem(json.loads(dumps_json(gt))) is None, (preset, index)
            checked += 1
    scenes = ROOT / "generator" / "scenes"
    for path in sorted(scenes.glob("*.json")):
        gt = scene_gt_record(load_scene(path), source=path.stem)
        assert gt_problem(json.loads(dumps_json(gt))) is None, path
        checked += 1
    assert checked >= 8


def test_json_helpers_write_null_for_undefined_numbers():
    import numpy as np

    obj = {"a": float("nan"), "b": [np.float64("inf"), np.float32(1.5), 2], "c": (np.int64(3),)}
    assert strict_json(dumps_json(obj)) == {"a": None, "b": [None, 1.5, 2], "c": [3]}
    assert strict_json(dumps_json_line(obj)) == {"a": None, "b": [None, 1.5, 2], "c": [3]}


def test_no_json_is_written_outside_the_shared_helpers():
    root = ROOT
    offenders = [
        f"{path.relative_to(root)}:{n}"
        for folder in ("src", "eval", "generator")
        for path in sorted((root / folder).rglob("*.py"))
        for n, line in enumerate(path.read_text().splitlines(), 1)
        if ("json.dumps(" in line or "json.dump(" in line)
        # warm_server.py runs inside the sandbox with the standard library only (its socket
        # protocol, not a file); jsonstream.py is the streamed form of fileio's helpers
        and path.name not in ("fileio.py", "result.py", "doctor.py", "warm_server.py",
                              "jsonstream.py")
    ]
    assert not offenders, offenders


@pytest.mark.integration
def test_compare_reads_reports_with_undefined_numbers(toy, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert run("eval", str(toy), "--pipeline", "liar:nan_area", "--out", str(a),
               "--no-progress", "--formats", "json").returncode == 0
    assert run("eval", str(toy), "--pipeline", "toy_arena:detect", "--out", str(b),
               "--no-progress", "--formats", "json").returncode == 0
    proc = run("eval", "--compare", str(a / "report.json"), str(b / "report.json"))
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    assert "pass_rate" in proc.stdout


# -------------------------------------------------------------------- bad --out paths


def _out_commands(toy: Path, tmp: Path) -> dict[str, tuple[str, ...]]:
    """Each command with valid arguments up to --out (the last argument is replaced)."""
    scene = ROOT / "generator" / "scenes" / "task1c_example.json"
    return {
        "eval": ("eval", str(toy), "--pipeline", "toy_arena:detect", "--no-progress", "--out"),
        "sweep": ("sweep", "--vary", "camera.tilt_deg=0:10", "--pipeline", "reference",
                  "--per-point", "1", "--no-progress", "--out"),
        "generate": ("generate", "--count", "1", "--no-progress", "--out"),
        "contact-sheet": ("contact-sheet", "--count", "1", "--out"),
        "fit": ("fit", str(EXAMPLE), "--out"),
        "render": ("render", str(scene), "--out"),
        "bench": ("bench", "--quick", "--out"),
        "detect": ("detect", "--image", str(EXAMPLE), "--output"),
    }


@pytest.mark.parametrize("command", ["eval", "sweep", "generate", "contact-sheet", "fit",
                                     "render", "bench", "detect"])
@pytest.mark.parametrize("where", ["file", "under-file", "proc", "read-only"])
def test_unwritable_out_is_refused_before_any_work(toy, tmp_path, command, where):
    blocker = tmp_path / "blocker.jpg"
    blocker.write_text("a file in the way\n")
    target = {
        "file": blocker, "under-file": blocker / "x.jpg", "proc": Path("/proc/arenabench.jpg"),
        "read-only": Path("/sys/arenabench.jpg"),
    }[where]
    if where == "file" and command in ("contact-sheet", "fit", "detect"):
        target = tmp_path / "folder.jpg"  # a file output where a folder is
        target.mkdir()
    argv = _out_commands(toy, tmp_path)[command]
    flag = argv[-1]
    proc = run(*argv, str(target), cwd=tmp_path)
    assert_clean_error(proc, f"{flag} {target}: ", prog=command)
    assert blocker.read_text() == "a file in the way\n"


# ---------------------------------------------------------------------- absurd sizes


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (("generate", "--count", str(10**12)), "--count: must be an integer in [1, 1000000]"),
        (("generate", "--count", "1", "--set", "camera.width=200000"), "out of range [16, 8192]"),
        (("sweep", "--vary", "camera.tilt_deg=0:10", "--pipeline", "reference",
          "--per-point", str(10**12)), "exceeds the limit of 1000000"),
        (("sweep", "--vary", "camera.tilt_deg=0:10", "--pipeline", "reference",
          "--random", str(10**12)), "exceeds the limit of 1000000"),
        (("sweep", "--vary", "camera.yaw_deg=0:99.99:0.01", "--vary",
          "lighting.ambient=0:0.9999:0.0001", "--vary", "camera.roll_deg=0:9.999:0.001",
          "--pipeline", "reference", "--per-point", "1"), "exceeds the limit of 1000000"),
        (("contact-sheet", "--count", str(10**12)), "[1, 1000000]"),
        (("contact-sheet", "--tile", "200000"), "tile = 200000 exceeds the limit of 8192"),
        (("detect", "--image", str(EXAMPLE), "--frame-size", "200000"), "[16, 8192]"),
        (("generate", "--count", "1", "--workers", str(10**12)), "in [1, 256]"),
        (("sweep", "--vary", "camera.tilt_deg=0:10", "--pipeline", "reference",
          "--workers", str(10**12)), "in [1, 256]"),
        (("eval", ".", "--pipeline", "reference", "--workers", str(10**12)), "in [1, 256]"),
        (("eval", ".", "--pipeline", "reference", "--tolerance", "nan"), "finite number in [0, 1]"),
        (("eval", ".", "--pipeline", "reference", "--fail-under", "pass_rate=nan"),
         "--fail-under pass_rate=nan: not a number"),
    ],
)
def test_absurd_sizes_are_refused_at_once(tmp_path, argv, needle):
    out = ("--out", str(tmp_path / ("o.jpg" if argv[0] == "contact-sheet" else "o")))
    proc = run(*argv, *(out if argv[0] not in ("detect", "eval") else ()), cwd=tmp_path)
    assert_clean_error(proc, needle, prog=argv[0])
    assert not (tmp_path / "o").exists() and not (tmp_path / "o.jpg").exists()


def test_scene_file_wider_than_the_limit_is_refused(tmp_path):
    scene_src = ROOT / "generator" / "scenes"
    scene = json.loads((scene_src / "task1c_example.json").read_text())
    scene["camera"]["width"] = 200000
    path = tmp_path / "wide.json"
    path.write_text(json.dumps(scene))
    proc = run("render", str(path), "--out", str(tmp_path / "o"))
    assert_clean_error(proc, "camera.width must be an integer in [16, 8192]", prog="render")


# ---------------------------------------------------------------- detect: FIFO, devices


def test_detect_on_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "image.png"
    os.mkfifo(fifo)
    proc = run_process("detect", "--image", str(fifo), "--output", str(tmp_path / "o.txt"),
                       timeout=60)
    assert_clean_error(proc, "not a regular file", prog="detect")


@pytest.mark.parametrize("command", integration_but(["compare", "render", "eval-gt"], "compare"))
def test_other_inputs_that_are_fifos_are_refused_without_blocking(toy, tmp_path, command):
    import shutil

    fifo = tmp_path / "input.json"
    os.mkfifo(fifo)
    if command == "compare":
        proc = run_process("eval", "--compare", str(fifo), str(fifo), timeout=60)
        assert_clean_error(proc, "not a regular file", prog="eval")
    elif command == "render":
        proc = run_process("render", str(fifo), "--out", str(tmp_path / "o"), timeout=60)
        assert_clean_error(proc, "not a regular file", prog="render")
    else:
        bad = tmp_path / "bad"
        shutil.copytree(toy, bad)
        (bad / "gt" / "000001.json").unlink()
        os.mkfifo(bad / "gt" / "000001.json")
        proc = run_process("eval", str(bad), "--pipeline", "toy_arena:detect", timeout=60)
        assert_clean_error(proc, "gt/000001.json is not a regular file", prog="eval")


@pytest.mark.parametrize("name", integration_but(
    ["dataset.json", "manifest.jsonl", "gt/000001.json", "images/000001.png"], "manifest.jsonl"))
@pytest.mark.parametrize("command", integration_but(["eval", "grade"], "eval"))
def test_dataset_files_that_are_fifos_are_refused_without_blocking(toy, tmp_path, command,
                                                                    name):
    import shutil

    from procs_limit import GRADE_ARGS

    bad = tmp_path / "bad"
    shutil.copytree(toy, bad)
    (bad / name).unlink(missing_ok=True)
    os.mkfifo(bad / name)
    out = tmp_path / "out"
    if command == "eval":
        proc = run_process("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress",
                           "--out", str(out), timeout=60)
    else:
        (tmp_path / "teams" / "a").mkdir(parents=True)
        proc = run_process("grade", str(bad), str(tmp_path / "teams"), "--out", str(out),
                           "--allow-guessable-seed", "--no-progress", *GRADE_ARGS, timeout=60)
    assert_clean_error(proc, str(bad / name), "not a regular file", prog=command)
    assert not out.exists()


def test_reading_a_dataset_file_never_opens_a_fifo(tmp_path):
    """The one reader of dataset files refuses what is not a regular file from its open
    descriptor: a FIFO never blocks it, even when it appears after a check by name."""
    from arenabench.fileio import NotRegularFileError, read_regular, sha256_file

    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for read in (read_regular, sha256_file):
        with pytest.raises(NotRegularFileError, match="not a regular file"):
            read(fifo)
    with pytest.raises(NotRegularFileError, match="a directory"):
        read_regular(tmp_path)
    (tmp_path / "f").write_bytes(b"12345")
    assert read_regular(tmp_path / "f") == b"12345"
    with pytest.raises(OSError, match="more than the 4 bytes allowed"):
        read_regular(tmp_path / "f", limit=4)


def test_detect_output_dash_is_stdout(tmp_path):
    proc = run_process("detect", "--image", str(EXAMPLE), "--output", "-", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("Aruco ID: [80, 85, 90, 95]\nObstacles: 2\n")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("device", ["/dev/stdout", "/dev/null"])
def test_detect_writes_through_devices_and_never_replaces_them(tmp_path, device):
    before = os.lstat(device)
    proc = run_process("detect", "--image", str(EXAMPLE), "--output", device, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    after = os.lstat(device)
    assert (after.st_ino, stat.S_IFMT(after.st_mode)) == (before.st_ino,
                                                          stat.S_IFMT(before.st_mode))
    if device == "/dev/stdout":
        assert "Obstacles: 2" in proc.stdout


# ------------------------------------------------------------------ manifest hashes


@pytest.mark.integration
@pytest.mark.parametrize("damage", ["truncate", "swap", "gt"])
def test_damaged_dataset_is_refused_and_no_verify_skips_the_check(toy, tmp_path, damage):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(toy, bad)
    img0, img1 = bad / "images" / "000000.png", bad / "images" / "000001.png"
    if damage == "truncate":
        img0.write_bytes(img0.read_bytes()[:200])
        where = "images/000000.png"
    elif damage == "swap":
        a, b = img0.read_bytes(), img1.read_bytes()
        img0.write_bytes(b)
        img1.write_bytes(a)
        where = "images/000000.png"
    else:
        gt = bad / "gt" / "000000.json"
        gt.write_text(gt.read_text().replace('"count": ', '"count":  ', 1))
        where = "gt/000000.json"
    proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress")
    assert_clean_error(proc, f"{bad / where}: content does not match", prog="eval")
    proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress",
               "--no-verify")
    if damage == "truncate":  # a PNG cut short: damaged whatever the manifest says
        assert_clean_error(proc, f"dataset damaged: {bad / where}: truncated PNG",
                           "--skip-damaged", prog="eval")
    else:
        assert "Traceback" not in proc.stderr and proc.returncode in (0, 1), proc.stderr


@pytest.mark.parametrize("damage", integration_but(["truncated", "empty", "text"], "truncated"))
@pytest.mark.parametrize("verify", integration_but([True, False], True))
def test_damaged_image_with_matching_hash_is_a_damaged_dataset(toy, tmp_path, damage, verify):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(toy, bad)
    img = bad / "images" / "000001.png"
    img.write_bytes({"truncated": img.read_bytes()[:300], "empty": b"",
                     "text": b"this is not an image\n"}[damage])
    rehash(bad)  # the manifest agrees with the damaged file
    why = {"truncated": "truncated PNG", "empty": "empty file", "text": "not an image file"}
    no_verify = () if verify else ("--no-verify",)
    out = tmp_path / "out"
    proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress",
               "--out", str(out), *no_verify)
    assert_clean_error(proc, f"dataset damaged: {img}: {why[damage]}", prog="eval")
    assert not out.exists()
    proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress",
               "--out", str(out), "--skip-damaged", *no_verify)
    assert proc.returncode == 0, proc.stderr
    assert "1 damaged image(s) left out" in proc.stderr and "Traceback" not in proc.stderr
    report = strict_json((out / "report.json").read_text())
    assert [i["id"] for i in report["images"]] == ["000000", "000002"]


@pytest.mark.parametrize("where", ["absolute", "dotdot", "symlink"])
def test_manifest_paths_that_leave_the_dataset_are_refused(toy, tmp_path, where):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(toy, bad)
    outside = tmp_path / "outside.png"
    shutil.copyfile(bad / "images" / "000001.png", outside)
    manifest = bad / "manifest.jsonl"
    rows = [json.loads(line) for line in manifest.read_text().splitlines()]
    if where == "absolute":
        rows[1]["image"] = str(outside)
    elif where == "dotdot":
        rows[1]["image"] = "images/../../outside.png"
    else:
        (bad / "images" / "000001.png").unlink()
        (bad / "images" / "000001.png").symlink_to(outside)
    manifest.write_text("".join(json.dumps(r) + "\n" for r in rows))
    for extra in ((), ("--no-verify",)):
        proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress", *extra)
        assert_clean_error(proc, ":2: image path", "leaves the dataset folder",
                           "a dataset is a closed folder", prog="eval")


def test_gt_area_1e_320_does_not_blame_the_pipeline():
    from arenabench.eval.scoring.metrics import score_image
    from arenabench.eval.scoring.results import Prediction, Truth

    truth = Truth(count=0, area=1e-320, marker_ids=(80, 85, 90, 95))
    ok = score_image(truth, Prediction(status="ok", count=0, area=0.0,
                                       marker_ids=(80, 85, 90, 95)))
    assert ok.passed and ok.area_err_kind == "absolute_px"
    off = score_image(truth, Prediction(status="ok", count=0, area=5.0,
                                        marker_ids=(80, 85, 90, 95)))
    assert off.category == "area_off" and off.area_rel_err == 5.0


def test_empty_formats_is_refused(toy, tmp_path):
    proc = run("eval", str(toy), "--pipeline", "toy_arena:detect", "--formats", " , ",
               "--out", str(tmp_path / "o"))
    assert_clean_error(proc, "argument --formats: ' , ': no format named", prog="eval")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", ["eval", "sweep", "grade"])
def test_cmd_template_without_image_is_refused(toy, tmp_path, command):
    cmd = "python3 map.py --fast"
    argv = {"eval": ("eval", str(toy), "--cmd", cmd),
            "sweep": ("sweep", "--vary", "camera.tilt_deg=0:10", "--cmd", cmd,
                      "--out", str(tmp_path / "o")),
            "grade": ("grade", str(toy), str(tmp_path), "--cmd", cmd,
                      "--out", str(tmp_path / "o"))}[command]
    proc = run(*argv, cwd=tmp_path)
    assert_clean_error(proc, "--cmd 'python3 map.py --fast': the template has no {image}",
                       prog=command)
    assert not (tmp_path / "o").exists()


@pytest.mark.integration
def test_cmd_name_and_compare_gate(toy, tmp_path):
    good, bad = tmp_path / "good", tmp_path / "bad"
    proc = run("eval", str(toy), "--pipeline", "toy_arena:detect", "--out", str(good),
               "--formats", "json", "--no-progress")
    assert proc.returncode == 0, proc.stderr
    cmd = f"{{python}} {PIPES / 'liar.py'} --image {{image}} --obstacles 'Obstacles: 7'"
    proc = run("eval", str(toy), "--cmd", cmd, "--name", "team liar", "--out", str(bad),
               "--formats", "json", "--no-progress")
    assert proc.returncode == 0, proc.stderr
    assert json.loads((bad / "report.json").read_text())["pipeline"] == "team liar"
    assert proc.stdout.startswith("team liar: pass rate 0.0 %")
    ok = run("eval", "--compare", str(good / "report.json"), str(bad / "report.json"))
    assert ok.returncode == 0  # no gate asked for
    gated = run("eval", "--compare", str(good / "report.json"), str(bad / "report.json"),
                "--fail-on-regression", "pass_rate=0.05")
    assert gated.returncode == 1 and "Traceback" not in gated.stderr
    assert gated.stderr.strip() == ("arenabench eval: FAILED: regression: pass_rate 1 -> 0 "
                                    "(worse by 1, more than 0.05)"), gated.stderr
    better = run("eval", "--compare", str(bad / "report.json"), str(good / "report.json"),
                 "--fail-on-regression", "pass_rate=0")
    assert better.returncode == 0, better.stderr
    typo = run("eval", "--compare", str(good / "report.json"), str(bad / "report.json"),
               "--fail-on-regression", "pas_rate=0")
    assert_clean_error(typo, "did you mean 'pass_rate'?", prog="eval")
    alone = run("eval", str(toy), "--pipeline", "reference", "--name", "x")
    assert_clean_error(alone, "--name names a --cmd pipeline", prog="eval")


def test_detect_into_a_closed_pipe_exits_141_quietly(tmp_path):
    for module in (("-m", "arenabench", "detect"), ("-m", "arenabench.detect")):
        proc = subprocess.run(
            f"{sys.executable} {' '.join(module)} --image {EXAMPLE} --output - | true; "
            "exit ${PIPESTATUS[0]}", shell=True, executable="/bin/bash", capture_output=True,
            text=True, timeout=120, cwd=tmp_path)
        assert proc.returncode == 141, proc.stderr
        assert proc.stderr == "", proc.stderr


@pytest.mark.integration
def test_manifest_without_hashes_needs_no_verify(toy, tmp_path):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(toy, bad)
    rows = [json.loads(line) for line in (bad / "manifest.jsonl").read_text().splitlines()]
    (bad / "manifest.jsonl").write_text(
        "".join(json.dumps({k: v for k, v in r.items() if "sha" not in k}) + "\n" for r in rows)
    )
    proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress")
    assert_clean_error(proc, "'image_sha256' missing", "--no-verify", prog="eval")
    proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress",
               "--no-verify")
    assert proc.returncode == 0, proc.stderr


# -------------------------------------------------------------- generate: lock, temp files


def test_second_generate_into_a_locked_folder_says_who_holds_it(tmp_path):
    out = tmp_path / "ds"
    with lock_folder(out, command="arenabench generate --seed 1 (test holder)"):
        proc = run("generate", "--count", "1", "--seed", "2", "--out", str(out),
                   "--no-progress")
    err = assert_clean_error(proc, "is being written by another run", f"pid {os.getpid()}",
                             "(test holder)", prog="generate")
    assert "--out" in err
    assert sorted(p.name for p in out.iterdir()) == []  # nothing written, lock released


@pytest.mark.parametrize("command", ["eval", "sweep", "grade", "demo"])
def test_every_command_writing_a_folder_takes_generates_lock(toy, tmp_path, command):
    from procs_limit import GRADE_ARGS

    out = tmp_path / "out"
    teams = tmp_path / "teams"
    (teams / "a").mkdir(parents=True)
    (teams / "a" / "map.py").write_text("print('hi')\n")
    argv = {"eval": ("eval", str(toy), "--pipeline", "toy_arena:detect", "--out", str(out)),
            "sweep": ("sweep", "--vary", "camera.tilt_deg=0:10", "--pipeline", "reference",
                      "--per-point", "1", "--out", str(out)),
            "grade": ("grade", str(toy), str(teams), "--out", str(out), *GRADE_ARGS),
            "demo": ("demo", "--count", "1", "--out", str(out))}[command]
    with lock_folder(out, command="arenabench eval (test holder)"):
        proc = run(*argv, "--no-progress", cwd=tmp_path)
        err = assert_clean_error(proc, f"--out {out}: {out} is being written by another run",
                                 f"pid {os.getpid()}", "(test holder)", prog=command)
        assert sorted(p.name for p in out.iterdir()) == [LOCK_FILE], err
    if command == "eval":  # free again: the run takes the lock, writes, leaves no lock file
        proc = run(*argv, "--no-progress", "--formats", "json", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
        assert sorted(p.name for p in out.iterdir()) == ["report.json"]


@pytest.mark.integration
def test_resumed_generate_removes_stale_temp_files_and_leaves_no_lock(tmp_path):
    out = tmp_path / "ds"
    proc = run("generate", "--count", "1", "--seed", "4", "--out", str(out), "--no-progress")
    assert proc.returncode == 0, proc.stderr
    assert not (out / LOCK_FILE).exists()
    # a killed run: dataset.json says incomplete, temp files lie around
    meta = json.loads((out / "dataset.json").read_text())
    meta["complete"] = False
    (out / "dataset.json").write_text(json.dumps(meta))
    stale = [out / "images" / ".000000.png.k1ll3d.tmp", out / "gt" / ".000000.json.x.tmp",
             out / ".manifest.jsonl.y.tmp"]
    for path in stale:
        path.write_bytes(b"half written")
    proc = run("generate", "--count", "1", "--seed", "4", "--out", str(out), "--no-progress")
    assert proc.returncode == 0, proc.stderr
    assert not any(p.exists() for p in stale)
    assert json.loads((out / "dataset.json").read_text())["complete"] is True
    assert not (out / LOCK_FILE).exists()


@pytest.mark.integration
def test_two_generate_runs_at_once_the_second_is_refused_then_the_first_resumes(tmp_path):
    import signal
    import time

    out = tmp_path / "ds"
    first = subprocess.Popen(
        [sys.executable, "-m", "arenabench", "generate", "--count", "6", "--seed", "1",
         "--workers", "1", "--out", str(out), "--no-progress"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 120
        while not (out / LOCK_FILE).exists():
            assert first.poll() is None and time.monotonic() < deadline, "no lock taken"
            time.sleep(0.05)
        second = run("generate", "--count", "6", "--seed", "2", "--out", str(out),
                     "--no-progress")
        assert_clean_error(second, "is being written by another run", f"pid {first.pid}",
                           "--seed 1", prog="generate")
    finally:
        first.send_signal(signal.SIGKILL)  # a killed run: the kernel releases its lock
        first.wait(timeout=60)
    resumed = run("generate", "--count", "6", "--seed", "1", "--workers", "1", "--out",
                  str(out), "--no-progress")
    assert resumed.returncode == 0, resumed.stderr
    seeds = {json.loads(p.read_text())["seed"] for p in (out / "gt").glob("*.json")}
    assert seeds == {1} and len(list((out / "gt").glob("*.json"))) == 6
    assert not [p for p in out.rglob(".*") if p.is_file()]  # no temp or lock file left


# ------------------------------- values that fail only when a scene is drawn or rendered


@pytest.mark.parametrize(
    ("value", "needle"),
    [
        ("markers.dictionary=NOPE", "unknown ArUco dictionary 'NOPE'"),
        ("markers.ids=80,85,90,100000", "id 100000 is not in DICT_4X4_100"),
        ("obstacles.count=50", "could not place obstacle"),
        ("markers.side_m=100", "no room for obstacles"),
        ("camera.altitude_m=0.01", "markers not in view"),
        ("camera.fov_deg=1", "markers not in view"),
    ],
)
def test_generate_values_that_fail_when_drawn_are_refused_before_any_file(tmp_path, value,
                                                                          needle):
    out = tmp_path / "ds"
    proc = run("generate", "--count", "2", "--workers", "1", "--out", str(out), "--set", value,
               "--no-progress")
    assert_clean_error(proc, needle, prog="generate")
    assert not out.exists()


@pytest.mark.integration
def test_generate_scene_failing_after_the_first_leaves_the_folder_as_it_was(tmp_path):
    """Seed 1 with obstacles.count=1:12: scenes 0-2 place their boxes, scene 3 cannot (so the
    check of scene 0 passes and the failure comes from a worker of the pool)."""
    out = tmp_path / "ds"
    base = ("generate", "--seed", "1", "--set", "obstacles.count=1:12", "--out", str(out),
            "--no-progress")
    proc = run(*base, "--count", "4", "--workers", "2")
    assert_clean_error(proc, "could not place obstacle", prog="generate")
    assert not out.exists()  # a new set: nothing left
    proc = run(*base, "--count", "3", "--workers", "1")
    assert proc.returncode == 0, proc.stderr  # the corrected command works
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    proc = run(*base, "--count", "4", "--workers", "1")
    assert_clean_error(proc, "could not place obstacle", prog="generate")
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before  # an extension that fails: the set as it was
    proc = run(*base, "--count", "3", "--workers", "1")
    assert proc.returncode == 0 and "already complete: 3 images" in proc.stdout, proc.stderr


@pytest.mark.integration
def test_generate_into_a_folder_whose_dataset_json_is_a_fifo_is_refused(tmp_path):
    out = tmp_path / "ds"
    out.mkdir()
    os.mkfifo(out / "dataset.json")
    proc = run_process("generate", "--count", "1", "--out", str(out), "--no-progress", timeout=60)
    assert_clean_error(proc, "dataset.json is not a regular file", prog="generate")
    assert sorted(p.name for p in out.iterdir()) == ["dataset.json"]


def _scene_text(edit: str) -> str:
    scene = json.loads((HERE.parent / "generator" / "scenes" / "task1c_example.json").read_text())
    if edit == "height-inf":
        scene["obstacles"][0]["height_m"] = math.inf
    elif edit == "length-1e309":
        scene["obstacles"][0]["length_m"] = 12345.678
        return json.dumps(scene).replace("12345.678", "1e309")
    elif edit == "center-1e300":
        scene["obstacles"][0]["center_m"] = [1e300, 0.0]
    elif edit == "5000-obstacles":
        scene["obstacles"] = scene["obstacles"][:1] * 5000
    elif edit == "50MB-file":
        scene["notes"] = "x" * (50 << 20)
    elif edit == "deeply-nested":
        return '{"arena": ' + "[" * 100_000 + "]" * 100_000 + "}"
    elif edit == "arena-a-list":
        scene["arena"] = [1, 2]
    elif edit == "dictionary-a-number":
        scene["markers"]["dictionary"] = 5
    return json.dumps(scene)


@pytest.mark.parametrize(
    ("edit", "needle"),
    integration_but([
        ("height-inf", "obstacle.height_m must be a finite number"),
        ("length-1e309", "obstacle.length_m must be a finite number"),
        ("center-1e300", "obstacle.center_m must be a finite number in [-1000000, 1000000]"),
        ("5000-obstacles", "number of obstacles = 5000 exceeds the limit of 1000"),
        ("50MB-file", "a scene file holds at most 8388608"),
        ("deeply-nested", "nested too deeply"),
        ("arena-a-list", "invalid scene description"),
        ("dictionary-a-number", "markers.dictionary must be text, got 5"),
    ], first=2),
)
def test_render_of_a_hostile_scene_file_is_one_line_and_writes_nothing(tmp_path, edit, needle):
    path = tmp_path / "scene.json"
    path.write_text(_scene_text(edit))
    out = tmp_path / "o"
    proc = run("render", str(path), "--out", str(out))
    assert_clean_error(proc, needle, prog="render")
    assert not out.exists()


@pytest.mark.parametrize("side", ["inf", "nan", "1e309", "-1"])
def test_fit_arena_side_that_is_not_a_finite_positive_length_is_refused(tmp_path, side):
    out = tmp_path / "scene.json"
    proc = run("fit", str(EXAMPLE), "--arena-side", side, "--out", str(out))
    needle = ("argument --arena-side: invalid float value" if side in ("inf", "nan")
              else "--arena-side must be")  # typed numbers are plain decimal
    assert_clean_error(proc, needle, prog="fit")
    assert not out.exists()


def test_demo_with_an_unknown_pipeline_is_refused_before_rendering(tmp_path):
    out = tmp_path / "demo"
    proc = run("demo", "--pipeline", "nosuch", "--out", str(out), "--no-progress")
    assert_clean_error(proc, "--pipeline", "'nosuch'", prog="demo")
    assert not out.exists()


def _broken_gl() -> dict[str, str]:
    import ctypes.util

    if ctypes.util.find_library("OSMesa"):
        pytest.skip("libOSMesa is installed here: PYOPENGL_PLATFORM=osmesa is not broken")
    return {"PYOPENGL_PLATFORM": "osmesa"}


@pytest.mark.parametrize("command", integration_but(["generate", "sweep", "render", "contact-sheet",
                                              "bench"], "render"))
def test_broken_opengl_is_one_line_pointing_at_doctor_and_leaves_nothing(tmp_path, command):
    env = _broken_gl()
    out = tmp_path / ("o.jpg" if command == "contact-sheet" else "o")
    argv = {
        "generate": ("generate", "--count", "1", "--no-progress"),
        "sweep": ("sweep", "--vary", "camera.tilt_deg=0:10", "--pipeline", "reference",
                  "--per-point", "1", "--no-progress"),
        "render": ("render", str(HERE.parent / "generator" / "scenes" / "task1c_example.json")),
        "contact-sheet": ("contact-sheet", "--count", "1", "--no-progress"),
        "bench": ("bench", "--quick"),
    }[command]
    proc = subprocess.run([sys.executable, "-m", "arenabench", *argv, "--out", str(out)],
                          capture_output=True, text=True, timeout=120,
                          env={**os.environ, **env})
    assert_clean_error(proc, "no off-screen OpenGL", "arenabench doctor", prog=command)
    assert not out.exists()


@pytest.mark.parametrize("text", ["[1]", '{"args": 5}', "[" * 100_000 + "]" * 100_000],
                         ids=["a-list", "args-a-number", "deeply-nested"])
def test_generate_into_a_folder_with_a_hostile_dataset_json_is_refused(tmp_path, text):
    out = tmp_path / "ds"
    out.mkdir()
    (out / "dataset.json").write_text(text)
    proc = run("generate", "--count", "1", "--out", str(out), "--no-progress")
    assert_clean_error(proc, "dataset.json is unreadable", prog="generate")
    assert sorted(p.name for p in out.iterdir()) == ["dataset.json"]
    assert (out / "dataset.json").read_text() == text


def test_render_into_a_generated_dataset_is_refused(toy, tmp_path):
    import shutil

    ds = tmp_path / "ds"
    shutil.copytree(toy, ds)
    (ds / "dataset.json").write_text("{}")
    before = {p: p.read_bytes() for p in ds.rglob("*") if p.is_file()}
    scene = HERE.parent / "generator" / "scenes" / "task1c_example.json"
    proc = run("render", str(scene), "--out", str(ds))
    assert_clean_error(proc, "holds a generated dataset", prog="render")
    assert {p: p.read_bytes() for p in ds.rglob("*") if p.is_file()} == before
@pytest.fixture()
def small_disk(tmp_path):
    """A 40 kB tmpfs (root only): room for report.json, not for report.html."""
    mnt = tmp_path / "small"
    mnt.mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=40k", "tmpfs", str(mnt)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here: {proc.stderr.strip()}")
    yield mnt
    subprocess.run(["umount", str(mnt)], check=True)


@pytest.mark.integration
def test_disk_full_while_writing_reports_is_one_line(toy, small_disk):
    out = small_disk / "out"
    proc = run("eval", str(toy), "--pipeline", "toy_arena:detect", "--out", str(out),
               "--no-progress")
    err = proc.stderr.strip()
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert err.splitlines() == [f"arenabench eval: error: disk full: {out}: No space left on "
                                "device (free some space or use another --out)"], err
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]  # no temp, no lock


def test_presets_show_of_an_empty_name_is_refused():
    proc = run("presets", "--show", "")
    assert_clean_error(proc, "unknown preset ''", prog="presets")


# --------------------------------------------------- --out: system folders, inputs, others' files


def _eval_argv(toy: Path) -> tuple[str, ...]:
    return ("eval", str(toy), "--pipeline", "toy_arena:detect", "--no-progress", "--formats",
            "json,csv,md,html,junit")


def test_eval_out_root_is_refused_and_writes_nothing_there(toy):
    from arenabench.eval.reports import FORMATS

    before = {name for name in FORMATS.values() if (Path("/") / name).exists()}
    try:
        proc = run(*_eval_argv(toy), "--out", "/")
        assert_clean_error(proc, "--out /: is a system folder (/ or a folder directly in it)",
                           prog="eval")
    finally:  # the unfixed command wrote its five reports into /
        for name in set(FORMATS.values()) - before:
            (Path("/") / name).unlink(missing_ok=True)
    assert {name for name in FORMATS.values() if (Path("/") / name).exists()} == before


@pytest.fixture()
def top_folder():
    """A new empty folder directly in / (removed afterwards, whatever was written in it)."""
    import shutil
    import uuid

    folder = Path("/") / f"arenabench-test-{uuid.uuid4().hex[:12]}"
    folder.mkdir()
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.parametrize("command", ["eval", "sweep", "grade", "generate"])
def test_out_leading_to_a_system_folder_is_refused(toy, tmp_path, top_folder, command):
    link = tmp_path / "top-link"
    link.symlink_to(top_folder)
    (tmp_path / "teams" / "a").mkdir(parents=True)
    argv = {"eval": _eval_argv(toy),
            "sweep": ("sweep", "--vary", "camera.tilt_deg=0:10", "--pipeline", "reference",
                      "--per-point", "1"),
            "grade": ("grade", str(toy), str(tmp_path / "teams")),
            "generate": ("generate", "--count", "1")}[command]
    proc = run(*argv, "--out", str(link), "--no-progress", cwd=tmp_path)
    assert_clean_error(proc, f"--out {link}: leads to {top_folder}, a system folder",
                       prog=command)
    assert list(top_folder.iterdir()) == []


@pytest.mark.parametrize("where", ["same", "inside", "images"])
@pytest.mark.parametrize("command", ["eval", "grade"])
def test_out_equal_to_or_inside_the_dataset_is_refused(toy, tmp_path, command, where):
    from procs_limit import GRADE_ARGS

    out = {"same": toy, "inside": toy / "reports", "images": toy / "images"}[where]
    (tmp_path / "teams" / "a").mkdir(parents=True)
    argv = {"eval": _eval_argv(toy),
            "grade": ("grade", str(toy), str(tmp_path / "teams"), *GRADE_ARGS)}[command]
    before = sorted(p.relative_to(toy) for p in toy.rglob("*"))
    proc = run(*argv, "--out", str(out), "--no-progress", cwd=tmp_path)
    assert_clean_error(proc, f"--out {out}: is {'' if where == 'same' else 'inside '}DATASET "
                       f"{toy} (inputs are only read)", prog=command)
    assert sorted(p.relative_to(toy) for p in toy.rglob("*")) == before


def test_check_out_inside_its_twin_set_is_refused(tmp_path, monkeypatch):
    from arenabench.eval.commands.check import twin_set_dir
    from arenabench.usercache import CACHE_ENV

    cache = tmp_path / "cache"
    monkeypatch.setenv(CACHE_ENV, str(cache))
    out = twin_set_dir(preset="eyrc", seed=0, count=2) / "reports"
    proc = run_cli("check", str(PIPES / "crash.py"), "--count", "2", "--out", str(out),
                   "--no-progress")
    assert_clean_error(proc, f"--out {out}: is inside the twin set", prog="check")
    assert not cache.exists()


@pytest.mark.parametrize("command", integration_but(["eval", "sweep", "check"], "eval"))
def test_out_holding_other_files_is_refused_and_an_earlier_report_is_not(toy, tmp_path,
                                                                         command):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me\n")
    argv = {"eval": _eval_argv(toy),
            "sweep": ("sweep", "--vary", "camera.tilt_deg=0:10", "--pipeline", "reference",
                      "--per-point", "1", "--no-progress"),
            "check": ("check", str(PIPES / "crash.py"), "--count", "2", "--no-progress")}[command]
    env = {"PYTHONPATH": _pythonpath(), "ARENABENCH_CACHE_DIR": str(tmp_path / "cache")}
    proc = run_cli(*argv, "--out", str(out), cwd=tmp_path, env=env)
    own = {"eval": "'arenabench eval' report", "sweep": "'arenabench sweep' output",
           "check": "'arenabench check' report"}[command]
    assert_clean_error(proc, f"--out {out}: not empty ('notes.txt') and holds no earlier {own}",
                       prog=command)
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    if command == "eval":  # a folder holding an earlier report is written again
        (out / "report.json").write_text("{}")
        proc = run_cli(*argv, "--out", str(out), cwd=tmp_path, env=env)
        assert proc.returncode == 0, proc.stderr
        assert json.loads((out / "report.json").read_text())["summary"]["n"] == 3


# --------------------------------------------------------------- --cmd placeholders, scripts


@pytest.mark.parametrize(("cmd", "needle"), [
    ("python3 map.py --image {imgae}", "unknown placeholder {imgae} (did you mean '{image}'?)"),
    ("python3 map.py --image {image} {nosuch}", "unknown placeholder {nosuch} in '{nosuch}'"),
    ("python3 map.py --image {image} --n={}", "empty placeholder {}"),
    ("python3 map.py --image {image!r}", "placeholder {image!r} takes no format spec"),
    ("python3 map.py --image {image} x}", "Single '}' encountered"),
])
@pytest.mark.parametrize("command", ["eval", "sweep"])
def test_cmd_with_an_unknown_placeholder_is_refused(toy, tmp_path, command, cmd, needle):
    (tmp_path / "map.py").write_text("print('hi')\n")
    argv = {"eval": ("eval", str(toy), "--cmd", cmd),
            "sweep": ("sweep", "--vary", "camera.tilt_deg=0:10", "--cmd", cmd)}[command]
    proc = run(*argv, "--out", str(tmp_path / "o"), "--no-progress", cwd=tmp_path)
    assert_clean_error(proc, f"--cmd {cmd!r}: ", needle, prog=command)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(("cmd", "needle"), [
    ("python3 {submision}/map.py --image {image}",
     "unknown placeholder {submision} (did you mean '{submission}'?)"),
    ("python3 {submission}/map.py --image {imgae}",
     "unknown placeholder {imgae} (did you mean '{image}'?)"),
    ("{python} {submission}/map.py --image {image}", "{python} is arenabench's own Python"),
])
def test_grade_cmd_with_a_placeholder_it_does_not_take_is_refused(toy, tmp_path, cmd, needle):
    from procs_limit import GRADE_ARGS

    (tmp_path / "teams" / "a").mkdir(parents=True)
    proc = run("grade", str(toy), str(tmp_path / "teams"), "--cmd", cmd, *GRADE_ARGS,
               "--out", str(tmp_path / "o"), "--no-progress", cwd=tmp_path)
    assert_clean_error(proc, f"--cmd {cmd!r}: ", needle, prog="grade")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", ["eval", "sweep"])
@pytest.mark.parametrize(("cmd", "needle"), [
    ("python3 mapp.py --image {image}",
     "script 'mapp.py' does not exist (relative to {tmp}) (did you mean 'map.py'?)"),
    ("python3 -u src/mapp.py --image {image}", "script 'src/mapp.py' does not exist"),
    ("{python} nosuch --image {image}", "script 'nosuch' does not exist"),
])
def test_cmd_naming_a_script_that_does_not_exist_is_refused(toy, tmp_path, command, cmd,
                                                            needle):
    (tmp_path / "map.py").write_text("print('hi')\n")
    (tmp_path / "src").mkdir()
    argv = {"eval": ("eval", str(toy), "--cmd", cmd),
            "sweep": ("sweep", "--vary", "camera.tilt_deg=0:10", "--cmd", cmd)}[command]
    proc = run(*argv, "--out", str(tmp_path / "o"), "--no-progress", cwd=tmp_path)
    err = assert_clean_error(proc, f"--cmd {cmd!r}: ", needle.format(tmp=tmp_path),
                             prog=command)
    assert "/sandbox" not in err
    assert not (tmp_path / "o").exists()


# ----------------------------------------------------------- --pipeline that is no pipeline


@pytest.mark.parametrize(("spec", "needle"), integration_but([
    ("../ci/mypipe.py:detect", "the part before ':' is a module name, not a file: name it "
                               "'mypipe:detect' and run from ../ci (or put ../ci on PYTHONPATH)"),
    ("refernce", "got 'refernce' (did you mean 'reference'?)"),
    ("os:system", "pipeline 'os:system': cannot take an image (TypeError: "),
    ("json:loads", "pipeline 'json:loads': cannot take an image (TypeError: the JSON object"),
    ("os:getcwd", "pipeline 'os:getcwd': getcwd() cannot be called with one image"),
    ("hostile_callables:two_arguments", "two_arguments(image, config) cannot be called with "
                                        "one image"),
    ("hostile_callables:tuple_answer", "returned tuple (2, 72000.0) for an image, not a result "
                                       "(a mapping, or an object with count and area"),
], first=2))
@pytest.mark.parametrize("command", integration_but(["eval", "sweep"], "eval"))
def test_pipeline_that_is_no_pipeline_is_refused_before_any_image(toy, tmp_path, command, spec,
                                                                   needle):
    argv = {"eval": ("eval", str(toy)),
            "sweep": ("sweep", "--vary", "camera.tilt_deg=0:10", "--per-point", "1")}[command]
    proc = run(*argv, "--pipeline", spec, "--out", str(tmp_path / "o"), "--no-progress",
               cwd=tmp_path)
    assert_clean_error(proc, needle, prog=command)
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------- tracebacks: links, permissions, disk


def _png_declaring(width: int, height: int) -> bytes:
    """A PNG whose header promises ``width`` x ``height`` px, holding a few bytes of pixels
    (complete otherwise: IHDR, IDAT, IEND)."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2,
                                                                0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\x00" * 64)) + chunk(b"IEND", b""))


@pytest.mark.integration
@pytest.mark.parametrize(("width", "height"), [(20000, 20000), (1000, 0), (8193, 10)])
def test_image_header_promising_an_impossible_size_is_a_damaged_dataset(toy, tmp_path, width,
                                                                         height):
    import shutil

    bad = tmp_path / "bad"
    shutil.copytree(toy, bad)
    img = bad / "images" / "000001.png"
    img.write_bytes(_png_declaring(width, height))
    rehash(bad)
    out = tmp_path / "out"
    proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress",
               "--out", str(out))
    assert_clean_error(proc, f"dataset damaged: {img}: its header declares {width} x {height} "
                       "px (a side is 1 to 8192 px)", prog="eval")
    assert not out.exists()
    proc = run("eval", str(bad), "--pipeline", "toy_arena:detect", "--no-progress",
               "--out", str(out), "--skip-damaged", "--formats", "json")
    assert proc.returncode == 0, proc.stderr
    assert "1 damaged image(s) left out" in proc.stderr
    assert [i["id"] for i in strict_json((out / "report.json").read_text())["images"]] == [
        "000000", "000002"]


@pytest.mark.parametrize("command", ["eval", "grade"])
def test_dataset_path_that_is_a_symbolic_link_loop_is_one_line(tmp_path, command):
    from procs_limit import GRADE_ARGS

    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    (tmp_path / "teams" / "t").mkdir(parents=True)
    argv = {"eval": ("eval", str(tmp_path / "a"), "--pipeline", "reference"),
            "grade": ("grade", str(tmp_path / "a"), str(tmp_path / "teams"), *GRADE_ARGS)
            }[command]
    proc = run(*argv, "--out", str(tmp_path / "o"), "--no-progress")
    assert_clean_error(proc, f"{tmp_path / 'a'}: a symbolic link loop", prog=command)
    assert not (tmp_path / "o").exists()
    if command == "grade":  # the submissions folder too
        proc = run("grade", str(tmp_path / "teams"), str(tmp_path / "a"), *GRADE_ARGS,
                   "--out", str(tmp_path / "o"))
        assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr


def _without_read_permission() -> list[str]:
    """The prefix that runs a command whose file permissions apply: root drops the
    capabilities that bypass them (setpriv), others need none."""
    import shutil

    if os.geteuid() != 0:
        return []
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("root, and no setpriv to drop CAP_DAC_OVERRIDE (util-linux)")
    return [setpriv, "--bounding-set=-dac_override,-dac_read_search", "--"]


@pytest.mark.parametrize("what", integration_but(["manifest.jsonl", "images"], "images"))
@pytest.mark.parametrize("command", integration_but(["eval", "grade"], "grade"))
def test_unreadable_dataset_file_or_folder_is_one_line(toy, tmp_path, command, what):
    import shutil

    from procs_limit import GRADE_ARGS

    prefix = _without_read_permission()
    data = tmp_path / "data"
    shutil.copytree(toy, data)
    (tmp_path / "teams" / "t").mkdir(parents=True)
    argv = {"eval": ("eval", str(data), "--pipeline", "toy_arena:detect"),
            "grade": ("grade", str(data), str(tmp_path / "teams"), *GRADE_ARGS)}[command]
    os.chmod(data / what, 0)
    try:  # a real process: the capabilities it drops are its own
        proc = subprocess.run([*prefix, sys.executable, "-m", "arenabench", *argv, "--out",
                               str(tmp_path / "o"), "--no-progress"], capture_output=True,
                              text=True, timeout=TIMEOUT_S,
                              env={**os.environ, "PYTHONPATH": _pythonpath()})
    finally:
        os.chmod(data / what, 0o755 if what == "images" else 0o644)
    shown = data / what if what == "manifest.jsonl" else data / "images" / "000000.png"
    assert_clean_error(proc, f"{shown}: cannot read (Permission denied)", prog=command)
    assert not (tmp_path / "o").exists()


@pytest.mark.integration  # renders the two scenes of check's twin set
def test_check_out_on_a_full_disk_is_one_line(small_disk, tmp_path):
    out = small_disk / "out"
    proc = run_cli("check", str(PIPES / "crash.py"), "--count", "2", "--out", str(out),
                   "--no-progress", "--phase-check", "off",
                   env={"ARENABENCH_CACHE_DIR": str(tmp_path / "cache")})
    err = proc.stderr.strip()
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert err.splitlines()[-1] == (f"arenabench check: error: disk full: {out}: No space "
                                    "left on device (free some space or use another --out)"), err
    assert not [p.name for p in out.iterdir() if p.name.startswith(".")]  # no temp, no lock
