"""SIGINT / SIGTERM stop ``arenabench generate`` and ``arenabench sweep`` cleanly.

Real commands in subprocesses: each is signalled once it has done some work and must exit
with 130 (SIGINT) or 143 (SIGTERM) within seconds, print one line and no traceback, leave
valid partial outputs and no process behind (workers, external commands); an interrupted
``generate`` resumes to files byte-identical to an uninterrupted run. A parent killed with
SIGKILL takes its workers with it.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from arenabench.cli import run
from arenabench.fileio import sha256_file
from arenabench.interrupts import Interrupted, checkpoint, stop_on_signals
from arenabench.local_pool import local_map

#: Long enough that a signal sent after the third image lands mid-run (a twin image takes
#: about 30 ms with one worker).
COUNT = 150
SEED = 3
#: Generous bound on how long a signalled command may take to exit (the machine is shared).
STOP_S = 20.0
#: What eval writes into --out, interrupted or not.
REPORT_FILES = ["junit.xml", "report.html", "report.json", "report.md", "results.csv"]


def _arenabench(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "arenabench", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _generate_args(out: Path, workers: int) -> list[str]:
    return ["generate", "--preset", "eyrc", "--count", str(COUNT), "--seed", str(SEED),
            "--out", str(out), "--workers", str(workers), "--no-progress"]


def _wait_until(proc: subprocess.Popen, ready, timeout: float = 180.0) -> None:
    deadline = time.monotonic() + timeout
    while not ready():
        assert proc.poll() is None, f"exited early ({proc.returncode}): {proc.communicate()}"
        assert time.monotonic() < deadline, "the command made no progress"
        time.sleep(0.05)


def _count(folder: Path) -> int:
    return len(list(folder.glob("*"))) if folder.is_dir() else 0


def _descendants(pid: int) -> dict[int, str]:
    """Live descendants of ``pid``: {pid: command line}."""
    parents: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            fields = stat.rsplit(")", 1)[1].split()
            if fields[0] != "Z":
                parents[int(entry)] = int(fields[1])
    found, frontier = {}, [pid]
    while frontier:
        parent = frontier.pop()
        for child, ppid in parents.items():
            if ppid == parent and child not in found:
                found[child] = _cmdline(child)
                frontier.append(child)
    return found


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def _still_alive(procs: dict[int, str], wait_s: float = 10.0) -> dict[int, str]:
    """Those of ``procs`` (pid: command line) still running (not zombies) after ``wait_s``."""
    deadline = time.monotonic() + wait_s
    while True:
        alive = {}
        for pid, cmd in procs.items():
            try:
                state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
            except OSError:
                continue
            if state != "Z" and _cmdline(pid) == cmd:
                alive[pid] = cmd
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.1)


def _stop(proc: subprocess.Popen, sig: int) -> tuple[int, str, float, dict[int, str]]:
    """Signal ``proc``; its exit status, stderr, seconds to exit, descendants at the signal."""
    kids = _descendants(proc.pid)
    t0 = time.monotonic()
    proc.send_signal(sig)
    try:
        _, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    return proc.returncode, err, time.monotonic() - t0, kids


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    out = tmp_path_factory.mktemp("gen") / "full"
    proc = _arenabench(*_generate_args(out, 2))
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == 0, err
    return out


def test_stop_on_signals_raises_once_and_defers():
    with stop_on_signals() as stop:
        with pytest.raises(Interrupted) as info:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(5)
        assert info.value.exit_code == 143 and stop.exit_code == 143
        stop.check()  # raised once only
    with stop_on_signals() as stop:
        with pytest.raises(Interrupted):
            with stop.deferred():
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(0.2)
                done = True  # the block ran to its end
        assert done and stop.signal_name == "SIGINT" and stop.exit_code == 130
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def _swallowed_signal(sig: int = signal.SIGINT) -> None:
    """What trimesh does around its imports: ``except BaseException`` eats the Interrupted."""
    try:
        os.kill(os.getpid(), sig)
        time.sleep(5)
    except BaseException:  # the library's habit under test
        pass


def test_a_stop_a_library_swallowed_is_raised_again_at_the_next_checkpoint():
    checkpoint()  # outside a stop_on_signals block: nothing to raise
    with stop_on_signals() as stop:
        _swallowed_signal()
        assert stop.requested
        with stop.deferred():
            checkpoint()  # held back while a deferred block runs
        with pytest.raises(Interrupted) as info:  # ... and raised when it ends
            checkpoint()
        assert info.value.exit_code == 130
    checkpoint()  # the block is left: nothing pending any more


def test_local_map_stops_after_the_task_that_swallowed_the_stop():
    ran = []

    def task(i: int) -> int:
        ran.append(i)
        if i == 1:
            _swallowed_signal(signal.SIGTERM)
        return i

    got = []
    with stop_on_signals(), pytest.raises(Interrupted) as info:
        for value in local_map(task, range(5), workers=1):
            got.append(value)
    assert ran == [0, 1] and got == [0, 1] and info.value.signum == signal.SIGTERM


def test_a_command_that_returns_0_after_a_stop_exits_with_its_status(capsys):
    def command() -> int:
        with stop_on_signals():
            _swallowed_signal()
        return 0

    assert run(command) == 130
    assert capsys.readouterr().err == (
        "arenabench: SIGINT arrived as the command finished; its outputs are complete\n")
    assert run(lambda: 0) == 0  # the next command starts afresh


@pytest.mark.integration
@pytest.mark.parametrize(("sig", "workers"), [(signal.SIGINT, 2), (signal.SIGTERM, 1)])
def test_generate_stops_keeps_what_finished_and_resumes_byte_identical(
        tmp_path, uninterrupted, sig, workers):
    out = tmp_path / "ds"
    proc = _arenabench(*_generate_args(out, workers))
    _wait_until(proc, lambda: _count(out / "gt") >= 3)
    # what a worker killed in the middle of a write leaves (one that did not unwind in its
    # grace time): the stopped run removes it
    for name in ("images/.000098.jpg.k1ll3d.tmp", "gt/.000098.json.k1ll3d.tmp"):
        (out / name).write_bytes(b"half")
    rc, err, seconds, kids = _stop(proc, sig)
    assert rc == 128 + sig, err
    assert seconds < STOP_S
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "interrupted by" in lines[0], err
    assert f"of {COUNT} images written" in lines[0] and "again to resume" in lines[0]
    assert _still_alive(kids) == {}
    # the partial dataset is consistent: the manifest lists exactly the scenes on disk
    meta = json.loads((out / "dataset.json").read_text())
    assert meta["complete"] is False
    manifest = [json.loads(x) for x in (out / "manifest.jsonl").read_text().splitlines()]
    on_disk = sorted(p.stem for p in (out / "gt").glob("*.json")
                     if (out / "images" / f"{p.stem}.jpg").is_file())  # eyrc writes JPEG
    assert [m["id"] for m in manifest] == on_disk and meta["finished"] == len(on_disk)
    assert 3 <= len(on_disk) < COUNT and f"{len(on_disk)} of {COUNT}" in lines[0]
    for m in manifest:
        assert sha256_file(out / m["image"]) == m["image_sha256"]
        assert sha256_file(out / m["gt"]) == m["gt_sha256"]
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]
    # running it again finishes the job: the same bytes as a run never interrupted
    again = _arenabench(*_generate_args(out, 2))
    _, err = again.communicate(timeout=600)
    assert again.returncode == 0, err
    assert _files(out) == _files(uninterrupted)


@pytest.mark.integration
def test_generate_workers_die_with_a_killed_parent(tmp_path):
    out = tmp_path / "ds"
    proc = _arenabench(*_generate_args(out, 2))
    _wait_until(proc, lambda: _count(out / "gt") >= 2)
    rc, _, _, kids = _stop(proc, signal.SIGKILL)
    assert rc == -signal.SIGKILL
    assert any("multiprocessing" in cmd for cmd in kids.values())
    assert _still_alive(kids) == {}


#: Points x scenes per point of the interrupted sweeps: long enough to stop mid-run.
SWEEP_PER_POINT = 60
SWEEP_SAMPLES = 3 * SWEEP_PER_POINT


def _sweep_args(out: Path, workers: int, *pipes: str) -> list[str]:
    return ["sweep", "--preset", "eyrc", "--vary", "camera.tilt_deg=0:20:10",
            "--per-point", str(SWEEP_PER_POINT), "--seed", str(SEED), *pipes, "--out", str(out),
            "--workers", str(workers), "--no-progress", "--no-plots"]


@pytest.mark.integration
def test_sweep_stops_and_writes_what_finished(tmp_path):
    out = tmp_path / "sweep"
    proc = _arenabench(*_sweep_args(out, 2, "--pipeline", "reference", "--keep-images"))
    _wait_until(proc, lambda: _count(out / "gt") >= 3)
    rc, err, seconds, kids = _stop(proc, signal.SIGINT)
    assert rc == 130, err
    assert seconds < STOP_S
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "interrupted by SIGINT" in lines[0], err
    assert _still_alive(kids) == {}
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["complete"] is False and doc["run"]["interrupted"] == "SIGINT"
    done = doc["run"]["samples_done"]
    assert 3 <= done < SWEEP_SAMPLES and doc["run"]["samples"] == SWEEP_SAMPLES
    assert f"{done} of {SWEEP_SAMPLES} samples done" in lines[0]
    rows = (out / "results.jsonl").read_text().splitlines()
    assert len(rows) == done
    assert sum(p["summary"]["n"] for p in doc["points"]) == done
    assert (out / "sweep.csv").is_file()


@pytest.mark.integration
@pytest.mark.parametrize("workers", [1, 2])
def test_sweep_stop_ends_hanging_commands(tmp_path, workers):
    out = tmp_path / "sweep"
    tag = f"arenabench-test-hang-{os.getpid()}-{workers}"
    cmd = f"{{python}} -c \"import time; time.sleep(300)\" {tag} {{image}}"
    proc = _arenabench(*_sweep_args(out, workers, "--cmd", cmd))
    # a child forked but not yet exec'd shows the sweep's own command line (which holds the
    # tag too: a subprocess the sweep starts before its tasks): only the command counts. And
    # the trial build of the command, before the sweep takes its stop handler and its --out
    # lock, starts processes with the tag too: the lock says the sweep itself is running
    own = _cmdline(proc.pid)
    _wait_until(proc, lambda: (out / ".arenabench.lock").exists() and any(
        tag in c and c != own for c in _descendants(proc.pid).values()))
    rc, err, seconds, kids = _stop(proc, signal.SIGTERM)
    assert rc == 143, err
    assert seconds < STOP_S
    assert "Traceback" not in err and "interrupted by SIGTERM" in err
    assert any(tag in c for c in kids.values())
    assert _still_alive(kids) == {}
    doc = json.loads((out / "sweep.json").read_text())
    assert doc["complete"] is False and doc["run"]["samples_done"] == 0


@pytest.mark.integration
def test_sweep_on_a_dask_cluster_stops_and_cancels_its_tasks(tmp_path):
    distributed = pytest.importorskip("distributed")
    out = tmp_path / "sweep"
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster, \
            distributed.Client(cluster.scheduler_address) as client:
        args = _sweep_args(out, 1, "--pipeline", "reference", "--keep-images")
        args[args.index("--workers"):args.index("--workers") + 2] = [
            "--scheduler", cluster.scheduler_address]
        proc = _arenabench(*args)
        _wait_until(proc, lambda: _count(out / "gt") >= 2)
        rc, err, seconds, _ = _stop(proc, signal.SIGINT)
        assert rc == 130, err
        assert seconds < STOP_S
        assert "Traceback" not in err and "interrupted by SIGINT" in err
        doc = json.loads((out / "sweep.json").read_text())
        assert doc["complete"] is False and doc["run"]["samples_done"] >= 2

        def tasks_left(dask_scheduler):
            return len(dask_scheduler.tasks)

        deadline = time.monotonic() + 30
        while client.run_on_scheduler(tasks_left) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert client.run_on_scheduler(tasks_left) == 0
        assert len(client.scheduler_info()["workers"]) == 1  # the cluster's own workers stay


# ------------------------------------------------------------- a second Ctrl-C (the user insists)


def _double_sigint(proc: subprocess.Popen, delay: float) -> tuple[int, str]:
    proc.send_signal(signal.SIGINT)
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    return proc.returncode, err


@pytest.fixture(scope="module")
def toy3(tmp_path_factory):
    import toy_arena

    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("dbl") / "toy", n=3, seed=2)


#: A script that says when it starts (a file ``run-N`` in MARKS, N counting its runs: the
#: commands below run with --sandbox none, so it can write there), answers at once on its
#: first FAST runs and sleeps on the others: the tests wait for these files, not for a time.
MARKED = """\
import os, time
marks, fast = {marks!r}, {fast}
n = len([f for f in os.listdir(marks) if f.startswith("run-")])
open(os.path.join(marks, f"run-{{n}}"), "w").close()
if n >= fast:
    time.sleep(300)
open("obstacles.txt", "w").write("Obstacles: 0\\nArea: 0.0\\n")
"""


def _marked(folder: Path, *, fast: int) -> tuple[Path, Path]:
    """The script (``folder/map.py``) and its marks folder."""
    marks = folder / "marks"
    marks.mkdir(parents=True)
    script = folder / "map.py"
    script.write_text(MARKED.format(marks=str(marks), fast=fast))
    return script, marks


@pytest.mark.integration
@pytest.mark.parametrize("delay", [0.05, 0.3])
def test_second_sigint_eval_cmd_still_writes_every_partial_report(toy3, tmp_path, delay):
    script, marks = _marked(tmp_path, fast=1)
    out = tmp_path / "out"
    proc = _arenabench("eval", str(toy3), "--cmd", f"{sys.executable} {script} {{image}}",
                       "--workers", "1", "--sandbox", "none", "--no-progress", "--out", str(out))
    # the second image has started (one run at a time): the first has finished
    _wait_until(proc, lambda: (marks / "run-1").exists())
    rc, err = _double_sigint(proc, delay)
    assert rc == 130, err
    assert "Traceback" not in err
    assert sorted(p.name for p in out.iterdir()) == REPORT_FILES, err
    report = json.loads((out / "report.json").read_text())
    # the first image's result, never the second's (killed by the stop: not a result)
    assert report["complete"] is False and len(report["images"]) == 1, err
    assert "after 1 of 3 images" in err


@pytest.mark.integration
@pytest.mark.parametrize("delay", [0.05, 0.3])
def test_second_sigint_generate_exits_130_and_resumes(tmp_path, delay):
    out = tmp_path / "ds"
    proc = _arenabench(*_generate_args(out, 1))
    _wait_until(proc, lambda: _count(out / "images") >= 3)
    rc, err = _double_sigint(proc, delay)
    assert rc == 130, err
    assert "Traceback" not in err
    meta = json.loads((out / "dataset.json").read_text())
    assert meta["complete"] is False
    assert len((out / "manifest.jsonl").read_text().splitlines()) == meta["finished"]


@pytest.mark.integration
@pytest.mark.parametrize("delay", [0.05, 0.3])
def test_second_sigint_grade_exits_130(toy3, tmp_path, delay):
    teams = tmp_path / "teams"
    marks = {team: _marked(teams / team, fast=0)[1] for team in ("a", "b")}
    out = tmp_path / "out"
    from procs_limit import GRADE_ARGS, PY_CMD

    proc = _arenabench("grade", *GRADE_ARGS, str(toy3), str(teams), "--out", str(out),
                       "--workers", "2",
                       "--sandbox", "none", "--no-progress", "--allow-guessable-seed",
                       "--cmd", PY_CMD)
    _wait_until(proc, lambda: (marks["a"] / "run-0").exists())  # team a's runs have started
    rc, err = _double_sigint(proc, delay)
    assert rc == 130, err
    assert "Traceback" not in err
    assert not (out / ".arenabench.lock").exists()


@pytest.mark.integration
def test_eval_stopped_before_any_image_still_writes_empty_partial_reports(toy3, tmp_path):
    script, marks = _marked(tmp_path, fast=0)
    out = tmp_path / "out"
    proc = _arenabench("eval", str(toy3), "--cmd", f"{sys.executable} {script} {{image}}",
                       "--workers", "1", "--sandbox", "none", "--no-progress", "--out", str(out))
    _wait_until(proc, lambda: (marks / "run-0").exists())  # the first image is running
    rc, err = _double_sigint(proc, 0.05)
    assert rc == 130 and "Traceback" not in err, err
    report = json.loads((out / "report.json").read_text())
    assert report["complete"] is False and report["images"] == []
    assert sorted(p.name for p in out.iterdir()) == REPORT_FILES



@pytest.mark.integration
def test_a_stop_during_the_pyrender_import_waits_for_it_to_finish():
    """trimesh imports ``trimesh.path`` inside ``except BaseException`` and keeps an
    ExceptionWrapper in its place: a stop landing there was swallowed and broke the process
    (a later TypeError reported as a broken OpenGL context). The import now runs whole and
    the stop is raised after it. A fresh interpreter, signalled as ``trimesh.path`` starts."""
    code = """
import os, signal, sys
from arenabench.interrupts import Interrupted, stop_on_signals

sent = False

def tracer(frame, event, arg):
    global sent
    if event == "call" and frame.f_code.co_filename.endswith(
            os.path.join("trimesh", "path", "__init__.py")):
        sys.settrace(None)
        sent = True
        os.kill(os.getpid(), signal.SIGINT)

with stop_on_signals():
    sys.settrace(tracer)
    try:
        from arenabench.generator.dataset.make import worker_gl_info
        worker_gl_info()  # imports pyrender, hence trimesh
        print("not interrupted")
    except Interrupted:
        print("interrupted")
    sys.settrace(None)
if not sent:
    sys.exit("trimesh.path was not imported with pyrender: retarget this test")
import trimesh
from arenabench.generator.dataset.make import worker_gl_info
print(type(trimesh.path).__name__, "gl_renderer" in worker_gl_info())
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["interrupted", "module", "True"], done.stdout + done.stderr


# ------------------------------------------------------------- a stop during the phase check

#: A script wrong on every image at once, that hangs once the phase check re-runs it: run
#: number n (counted in MARKS, a folder it can write to: --sandbox none) past the set's images
#: writes ``phase-started`` and sleeps.
PHASE_HANG = """\
import os, sys, time
marks, images = {marks!r}, {images}
n = len([f for f in os.listdir(marks) if f.startswith("run-")])
open(os.path.join(marks, f"run-{{n}}-{{os.getpid()}}"), "w").close()
if n >= images:
    open(os.path.join(marks, "phase-started"), "w").close()
    time.sleep(300)
open("obstacles.txt", "w").write("Obstacles: 99\\nArea: 1.0\\n")
"""


@pytest.fixture(scope="module")
def twin2(shared_sets):
    """Two eyrc scenes: failures there are phase-checked (--phase-check auto)."""
    return shared_sets.generated("eyrc", count=2, seed=0)


def _phase_hang(folder: Path, marks: Path, images: int) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    marks.mkdir(parents=True, exist_ok=True)
    script = folder / "map.py"
    script.write_text(PHASE_HANG.format(marks=str(marks), images=images))
    return script


@pytest.mark.integration
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_eval_stopped_in_the_phase_check_ends_its_runs_at_once(twin2, tmp_path, sig):
    marks = tmp_path / "marks"
    script = _phase_hang(tmp_path / "team", marks, images=2)
    out = tmp_path / "out"
    proc = _arenabench("eval", str(twin2), "--cmd", f"{sys.executable} {script} {{image}}",
                       "--workers", "1", "--timeout", "300", "--sandbox", "none",
                       "--no-progress", "--out", str(out))
    _wait_until(proc, lambda: (marks / "phase-started").exists())
    # before the fix it waited for the re-runs' --timeout (300 s) and _stop killed it
    rc, err, _, kids = _stop(proc, sig)
    assert rc == 128 + sig, err
    assert "Traceback" not in err
    assert _still_alive(kids) == {}
    report = json.loads((out / "report.json").read_text())
    # both images scored; their phase check did not finish
    assert report["complete"] is False and len(report["images"]) == 2
    assert all(i["category"] == "wrong_count" and "phase" not in i for i in report["images"])


@pytest.mark.integration
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_grade_stopped_in_a_team_phase_check_ends_its_report_workers(twin2, tmp_path, sig):
    marks = tmp_path / "marks"
    subs = tmp_path / "subs"
    _phase_hang(subs / "a_hangs_in_phase_check", marks, images=2)
    (subs / "b_sleeps").mkdir()
    (subs / "b_sleeps" / "map.py").write_text("import time\ntime.sleep(300)\n")
    out = tmp_path / "out"
    from procs_limit import GRADE_ARGS

    proc = _arenabench("grade", *GRADE_ARGS, str(twin2), str(subs), "--out", str(out),
                       "--workers", "1", "--report-workers", "2", "--timeout", "300",
                       "--sandbox", "none", "--no-progress", "--allow-guessable-seed",
                       "--cmd", f"{sys.executable} {{submission}}/map.py --image {{image}}")
    _wait_until(proc, lambda: (marks / "phase-started").exists())
    # before the fix it waited for the re-runs' --timeout (300 s) and _stop killed it
    rc, err, _, kids = _stop(proc, sig)
    assert rc == 128 + sig, err
    assert "Traceback" not in err
    assert any("multiprocessing" in c for c in kids.values())  # the report workers
    assert _still_alive(kids) == {}
    doc = json.loads((out / "leaderboard.json").read_text())
    assert doc["complete"] is False
    assert not (out / ".arenabench.lock").exists()


# ------------------------------------------- a stop before a report exists, or after the last image

FAST_MAP = "open('obstacles.txt', 'w').write('Obstacles: 0\\nArea: 0.0\\n')\n"


def _signal_in(real, sig=signal.SIGINT):
    """``real``, which sends ``sig`` to this process once it has done its work: the stop lands
    there (the handler raises at the next instruction, inside this call)."""

    def hooked(*args, **kwargs):
        result = real(*args, **kwargs)
        os.kill(os.getpid(), sig)
        return result

    return hooked


@pytest.mark.parametrize(("where", "sig"), [("loading the dataset", signal.SIGINT),
                                             ("building the pipeline", signal.SIGTERM)])
def test_eval_stopped_before_any_image_ran_writes_an_empty_partial_report(
        toy3, tmp_path, monkeypatch, where, sig):
    from clirun import run_cli

    import arenabench.eval.datasets.reader as dataset_reader
    import arenabench.eval.evaluation as evaluation

    if where == "loading the dataset":
        monkeypatch.setattr(dataset_reader, "load_dataset",
                            _signal_in(dataset_reader.load_dataset, sig))
    else:
        monkeypatch.setattr(evaluation, "make_pipeline",
                            _signal_in(evaluation.make_pipeline, sig))
    script = tmp_path / "map.py"
    script.write_text(FAST_MAP)
    out = tmp_path / "out"
    proc = run_cli("eval", str(toy3), "--cmd", f"{sys.executable} {script} --image {{image}}",
                   "--sandbox", "none", "--no-progress", "--out", str(out))
    assert proc.returncode == 128 + sig, proc.stderr
    assert "nothing more written" not in proc.stderr and "Traceback" not in proc.stderr
    assert "after 0 of" in proc.stderr or "after 0 images" in proc.stderr, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == REPORT_FILES
    report = json.loads((out / "report.json").read_text())
    assert report["complete"] is False and report["images"] == []
    # how many images there were to run is known once the dataset is read
    assert report.get("n_total") == (None if where == "loading the dataset" else 3)
    assert "INCOMPLETE: 0" in (out / "report.md").read_text()


@pytest.mark.integration
@pytest.mark.parametrize("where", ["closing the pipeline", "writing the reports"])
def test_eval_stopped_after_its_last_image_writes_the_whole_report(toy3, tmp_path, monkeypatch,
                                                                   where):
    from clirun import run_cli

    import arenabench.eval.reports as reports
    from arenabench.eval.runs import CommandPipeline

    if where == "closing the pipeline":
        monkeypatch.setattr(CommandPipeline, "close", _signal_in(CommandPipeline.close))
    else:  # after report.md, before report.html and junit.xml
        monkeypatch.setattr(reports, "write_markdown", _signal_in(reports.write_markdown))
    script = tmp_path / "map.py"
    script.write_text(FAST_MAP)
    out = tmp_path / "out"
    proc = run_cli("eval", str(toy3), "--cmd", f"{sys.executable} {script} --image {{image}}",
                   "--sandbox", "none", "--no-progress", "--out", str(out))
    assert proc.returncode == 130, proc.stderr
    assert "its outputs are complete" in proc.stderr and "Traceback" not in proc.stderr
    assert sorted(p.name for p in out.iterdir()) == REPORT_FILES  # none cut off
    report = json.loads((out / "report.json").read_text())
    assert report["complete"] is True and len(report["images"]) == 3


@pytest.mark.integration
def test_check_stopped_while_loading_its_twin_set_writes_an_empty_partial_report(
        tmp_path, monkeypatch):
    from clirun import run_cli

    import arenabench.eval.datasets.reader as dataset_reader

    (tmp_path / "team").mkdir()  # the script's folder is copied into every run's
    script = tmp_path / "team" / "map.py"
    script.write_text(FAST_MAP)
    cache, out = tmp_path / "cache", tmp_path / "out"
    env = {"ARENABENCH_CACHE_DIR": str(cache)}
    made = run_cli("check", str(script), "--count", "2", "--sandbox", "none", "--no-progress",
                   "--python", "{python}", "--out", str(tmp_path / "first"),
                   env=env)  # makes the twin set
    assert made.returncode == 1, made.stderr
    monkeypatch.setattr(dataset_reader, "load_dataset", _signal_in(dataset_reader.load_dataset))
    proc = run_cli("check", str(script), "--count", "2", "--sandbox", "none", "--no-progress",
                   "--python", "{python}", "--out", str(out), env=env)
    assert proc.returncode == 130, proc.stderr
    assert "nothing more written" not in proc.stderr and "Traceback" not in proc.stderr
    assert sorted(p.name for p in out.iterdir()) == REPORT_FILES
    report = json.loads((out / "report.json").read_text())
    assert report["complete"] is False and report["images"] == []
