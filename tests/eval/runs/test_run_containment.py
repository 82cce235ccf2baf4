"""What one run can do to the others: nothing. Real bubblewrap, real warm servers, real
cgroups, real CPU burners.

- A team whose runs fork CPU burners and then kill, stop or freeze what they can see, or fill
  every folder they can write, is graded before two honest teams: the honest teams' verdicts
  equal those of a grade without it, and nothing of its runs (process, cgroup, folder) is left.
- A warm run is pid 1 of a PID namespace of its own, as a cold run under ``--as-pid-1`` is.
- What a run writes is bounded in all (``--max-disk``: its box, a tmpfs), never on the
  machine's disk; ``/dev`` is read-only to it.
- A run that timed out while waiting for a CPU (the machine, not the pipeline, was slow) is
  run again and marked ``starved``; a hang is a plain timeout.
- A submission that ships a module of the same name as one the warm server preloads runs cold,
  as the competition would have run it; a warm crash prints the script's traceback alone.
- What a SIGKILLed command leaves (warm folders and nested cgroups, the preflight's folder) is
  removed by the next command's sweep; an in-process pipeline's detached child dies with eval.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
import uuid
from pathlib import Path

import pytest
import toy_arena
from clirun import run_cli
from hostile_util import processes_with, wait_for
from paths import TESTS

from arenabench.eval.runs import CommandPipeline, proctools
from arenabench.eval.runs.limits import RunLimits, RunSettings
from arenabench.eval.runs.sandbox import bwrap_problem, pids_cgroup_parent
from arenabench.eval.runs.stale import (
    OWNER_FILE,
    OWNERLESS_GRACE_S,
    make_warm_dir,
    sweep_stale_runs,
)
from arenabench.eval.scoring.results import HarnessError

PIPES = TESTS / "pipelines"
PY = sys.executable
needs_bwrap = pytest.mark.skipif(bwrap_problem() is not None, reason=str(bwrap_problem()))
CGROUP = pids_cgroup_parent()
needs_cgroup = pytest.mark.skipif(CGROUP is None, reason="no writable pids cgroup here")
#: Marks the attackers' burners on their command line (this test process's own: what another
#: run of the tests left is not counted here).
BURNER = f"arenabench-test-burner-{uuid.uuid4().hex[:12]}"

HONEST = textwrap.dedent("""\
    import os, sys, time
    import cv2
    from toy_arena import detect, obstacles_text

    image = sys.argv[sys.argv.index("--image") + 1]
    start = time.process_time()
    while time.process_time() - start < 1.0:  # a second of CPU: late when burners share it
        pass
    with open("obstacles.txt", "w") as fh:
        fh.write(obstacles_text(detect(cv2.imread(image))))
""")

_BURN = textwrap.dedent(f"""\
    import os, sys
    for _ in range(16):
        if os.fork() == 0:  # each in a session of its own: a scheduling group of its own
            os.setsid()
            os.execv(sys.executable, [sys.executable, "-c", "while True: pass", {BURNER!r}])
""")

ATTACKS = {
    # burners, then SIGKILL of its parent (a warm run's manager, before PID namespaces)
    "kill_parent": _BURN + textwrap.dedent("""\
        import signal
        if os.getppid() > 1:
            os.kill(os.getppid(), signal.SIGKILL)
        open("obstacles.txt", "w").write("Obstacles: 0\\nArea: 0\\n")
    """),
    # burners, then SIGSTOP of its parent
    "stop_parent": _BURN + textwrap.dedent("""\
        import signal
        if os.getppid() > 1:
            os.kill(os.getppid(), signal.SIGSTOP)
        open("obstacles.txt", "w").write("Obstacles: 0\\nArea: 0\\n")
    """),
    # SIGSTOP of every process it can see but itself (the server's standbys, before)
    "stop_everything": textwrap.dedent("""\
        import os, signal
        for name in os.listdir("/proc"):
            if name.isdigit() and int(name) != os.getpid():
                try:
                    os.kill(int(name), signal.SIGSTOP)
                except OSError:
                    pass
        open("obstacles.txt", "w").write("Obstacles: 0\\nArea: 0\\n")
    """),
    # 60 MB files into every folder it can write, until none takes more
    "fill_disk": textwrap.dedent("""\
        import os
        block = b"x" * (1 << 20)
        for folder in (".", "/tmp", "/dev/shm", os.environ.get("TMPDIR", "/tmp")):
            for i in range(1000):
                try:
                    with open(os.path.join(folder, f"fill-{i}.bin"), "wb") as fh:
                        for _ in range(60):
                            fh.write(block)
                except OSError:
                    break
        open("obstacles.txt", "w").write("Obstacles: 0\\nArea: 0\\n")
    """),
}


def _team(subs: Path, name: str, script: str) -> None:
    (subs / name).mkdir(parents=True)
    (subs / name / "map.py").write_text(script)
    shutil.copy(PIPES / "toy_arena.py", subs / name / "toy_arena.py")


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toy") / "toy", n=4, seed=3)


def _grade(dataset: Path, subs: Path, out: Path, *, prefix: list[str] | None = None,
           env: dict[str, str] | None = None) -> tuple[int, str, int]:
    """``arenabench grade`` in a process of its own: (exit status, stderr, its pid; under the
    ``unshare ... sh -c 'exec'`` prefix the same process)."""
    cmd = f"{PY} {{submission}}/map.py --image {{image}}"
    argv = [*(prefix or []), PY, "-m", "arenabench", "grade", str(dataset), str(subs),
            "--out", str(out), "--cmd", cmd, "--timeout", "8", "--workers", "2",
            "--phase-check", "off", "--allow-guessable-seed", "--no-progress",
            "--formats", "json", "--sandbox", "bwrap"]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, **(env or {})})
    _, err = proc.communicate(timeout=900)
    return proc.returncode, err, proc.pid


def _verdicts(out: Path, team: str) -> list[tuple]:
    doc = json.loads((out / "teams" / team / "report.json").read_text())
    return [(r["id"], r["pass"], r["category"], r["pred"]["count"], r["pred"]["area"])
            for r in doc["images"]]


@pytest.fixture(scope="module")
def honest_alone(toy, tmp_path_factory):
    root = tmp_path_factory.mktemp("alone")
    for name in ("z_honest1", "z_honest2"):
        _team(root / "subs", name, HONEST)
    code, err, _ = _grade(toy, root / "subs", root / "out")
    assert code == 0, err[-3000:]
    verdicts = {t: _verdicts(root / "out", t) for t in ("z_honest1", "z_honest2")}
    assert all(v[1] for t in verdicts.values() for v in t), verdicts  # honest teams pass
    return verdicts


def _small_tmpdir_prefix(tmpdir: Path) -> list[str] | None:
    """Run a command with ``tmpdir`` a 150 MB tmpfs of its own mount namespace (root)."""
    unshare = shutil.which("unshare")
    if os.getuid() != 0 or unshare is None:
        return None
    tmpdir.mkdir()
    return [unshare, "--mount", "--propagation", "private", "sh", "-c",
            f'mount -t tmpfs -o size=150m none {tmpdir} && exec "$@"', "sh"]


def _warm_cgroups_of(pid: int) -> list[str]:
    if CGROUP is None:
        return []
    return [p.name for p in Path(CGROUP).iterdir() if p.name.startswith(f"arenabench-warm-{pid}-")]


@pytest.mark.integration
@needs_bwrap
@pytest.mark.parametrize("attack", sorted(ATTACKS))
def test_one_team_cannot_sink_the_others(attack, toy, honest_alone, tmp_path):
    subs = tmp_path / "subs"
    _team(subs, "a_attacker", ATTACKS[attack])
    for name in ("z_honest1", "z_honest2"):
        _team(subs, name, HONEST)
    prefix, env = None, None
    if attack == "fill_disk":  # the machine's temporary folder small enough to fill
        prefix = _small_tmpdir_prefix(tmp_path / "smalltmp")
        if prefix is None:
            pytest.skip("needs root and 'unshare --mount' for a small TMPDIR")
        env = {"TMPDIR": str(tmp_path / "smalltmp")}
    code, err, pid = _grade(toy, subs, tmp_path / "out", prefix=prefix, env=env)
    assert code == 0, err[-3000:]
    for team in ("z_honest1", "z_honest2"):
        assert _verdicts(tmp_path / "out", team) == honest_alone[team], (team, err[-3000:])
    attacker = json.loads((tmp_path / "out" / "teams" / "a_attacker" / "report.json")
                          .read_text())
    assert attacker["summary"]["n"] == 4
    # nothing of the attacker's runs outlives the command: no burner, no cgroup
    assert processes_with(BURNER) == []
    assert _warm_cgroups_of(pid) == []


def _pipe(script: Path, sandbox: str, *, warm: bool = True, **limits) -> CommandPipeline:
    return CommandPipeline(f"{PY} {script} --image {{image}}", settings=RunSettings(
        limits=RunLimits(**{"timeout_s": 30.0, **limits}), sandbox=sandbox, warm=warm))


PROBE_IDS = textwrap.dedent("""\
    import json, os
    open("obstacles.txt", "w").write("Obstacles: 0\\nArea: 0\\n")
    print(json.dumps({"pid": os.getpid(), "ppid": os.getppid(), "pgid": os.getpgid(0),
                      "sid": os.getsid(0)}))
""")


@needs_bwrap
@pytest.mark.parametrize("warm", [True, False])
def test_a_run_is_pid_1_of_its_own_namespace(warm, toy, tmp_path, run_tmp):
    script = tmp_path / "ids.py"
    script.write_text(PROBE_IDS)
    pred = _pipe(script, "bwrap", warm=warm).run(sorted((toy / "images").iterdir())[0])
    assert pred.status == "ok", (pred.message, pred.stderr)
    seen = json.loads(pred.stdout.strip().splitlines()[-1])
    assert seen == {"pid": 1, "ppid": 0, "pgid": 1, "sid": 1}


WRITER = textwrap.dedent("""\
    import errno, json, os
    written, errors = {}, {}
    for folder in (".", "/tmp", "/dev/shm", "/dev"):
        total = 0
        try:
            for i in range(100):
                with open(os.path.join(folder, f"w{i}.bin"), "wb") as fh:
                    for _ in range(8):
                        fh.write(b"x" * (1 << 20))
                        fh.flush()
                        total += 1 << 20
        except OSError as exc:
            errors[folder] = errno.errorcode.get(exc.errno, str(exc.errno))
        written[folder] = total
        for i in range(100):
            try:
                os.remove(os.path.join(folder, f"w{i}.bin"))
            except OSError:
                pass
    open("obstacles.txt", "w").write("Obstacles: 0\\nArea: 0\\n")
    print(json.dumps({"written": written, "errors": errors}))
""")


@needs_bwrap
@pytest.mark.parametrize("warm", [True, False])
def test_what_a_run_writes_is_bounded_by_max_disk(warm, toy, tmp_path, run_tmp):
    script = tmp_path / "writer.py"
    script.write_text(WRITER)
    pipe = _pipe(script, "bwrap", warm=warm, disk_bytes=24 << 20)
    pred = pipe.run(sorted((toy / "images").iterdir())[0])
    assert pred.status == "ok", (pred.message, pred.stderr)
    seen = json.loads(pred.stdout.strip().splitlines()[-1])
    for folder in (".", "/tmp", "/dev/shm"):  # one box of 24 MiB, each folder in turn
        assert seen["errors"][folder] in ("ENOSPC", "EDQUOT"), seen
        assert seen["written"][folder] <= 24 << 20, seen
    assert seen["errors"]["/dev"] in ("EROFS", "EACCES"), seen
    assert seen["written"]["/dev"] == 0


def test_copy_back_brings_the_answer_and_a_bounded_set_of_images(tmp_path):
    src, dst = tmp_path / "src", tmp_path / "dst"
    src.mkdir()
    dst.mkdir()
    (src / "obstacles.txt").write_text("Obstacles: 1\nArea: 2\n")
    (src / "warped.png").write_bytes(b"png" * 10)
    (src / "image.png").write_bytes(b"input")  # the input image's copy stays where it is
    (src / "notes.txt").write_text("not an image")
    (src / "link.png").symlink_to(src / "warped.png")
    os.mkfifo(src / "fifo.jpg")
    big = src / "big.png"
    with open(big, "wb") as fh:
        fh.truncate(proctools.RESULT_BYTES_MAX + 1)
    for i in range(40):
        (src / f"many{i:02d}.jpg").write_bytes(b"j")
    s, d = os.open(src, os.O_RDONLY), os.open(dst, os.O_RDONLY)
    try:
        proctools.copy_back(s, d, skip="image.png")
    finally:
        os.close(s)
        os.close(d)
    names = sorted(p.name for p in dst.iterdir())
    assert "obstacles.txt" in names and (dst / "obstacles.txt").read_text().startswith("Obst")
    assert "warped.png" in names or len(names) == proctools.RESULT_FILES_MAX
    assert not {"image.png", "notes.txt", "link.png", "fifo.jpg", "big.png"} & set(names)
    assert len(names) <= proctools.RESULT_FILES_MAX
    assert all((dst / n).is_file() and not (dst / n).is_symlink() for n in names)


@pytest.mark.parametrize("kind", ["folder", "link", "fifo", "large"])
def test_copy_back_keeps_what_kind_of_answer_it_was(kind, tmp_path):
    src, dst = tmp_path / "src", tmp_path / "dst"
    src.mkdir()
    dst.mkdir()
    answer = src / "obstacles.txt"
    if kind == "folder":
        answer.mkdir()
    elif kind == "link":
        answer.symlink_to("/etc/passwd")
    elif kind == "fifo":
        os.mkfifo(answer)
    else:
        with open(answer, "wb") as fh:
            fh.write(b"Obstacles: 1\n")
            fh.truncate(200 << 20)
    s, d = os.open(src, os.O_RDONLY), os.open(dst, os.O_RDONLY)
    try:
        proctools.copy_back(s, d, skip="image.png")
    finally:
        os.close(s)
        os.close(d)
    back = dst / "obstacles.txt"
    assert {"folder": back.is_dir, "link": back.is_symlink,
            "fifo": lambda: back.exists() and not back.is_file() and not back.is_dir(),
            "large": lambda: back.stat().st_size == 200 << 20}[kind]()
    if kind == "large":
        assert back.stat().st_blocks * 512 <= 2 * proctools.ANSWER_COPY_BYTES  # a hole


#: The one CPU the starvation test's run and burners share.
CPU = min(os.sched_getaffinity(0))
PINNED_BUSY = f"import os\nos.sched_setaffinity(0, {{{CPU}}})\nwhile True:\n    pass\n"
HANG = "import time\ntime.sleep(600)\n"


def _burners(n: int) -> list[subprocess.Popen]:
    return [subprocess.Popen([PY, "-c", PINNED_BUSY, BURNER]) for _ in range(n)]


@pytest.mark.integration
@pytest.mark.parametrize("warm", [True, False])
def test_a_run_starved_of_cpu_is_the_harness_failure_never_a_timeout(warm, toy, tmp_path,
                                                                     run_tmp):
    busy, hang = tmp_path / "busy.py", tmp_path / "hang.py"
    busy.write_text(PINNED_BUSY)
    hang.write_text(HANG)
    image = sorted((toy / "images").iterdir())[0]
    burners = _burners(6)  # the run gets at most half of the one CPU it may use (its session
    # is an autogroup of its own where the kernel has them; else a seventh)
    pipe = _pipe(busy, "none", warm=warm, timeout_s=2.0)
    try:
        with pytest.raises(HarnessError, match=r"starved of CPU .* in each of 3 runs") as err:
            pipe.run(image)
    finally:
        pipe.close()
        for b in burners:
            b.kill()
            b.wait()
    assert "fewer --workers" in str(err.value)
    idle = _pipe(hang, "none", warm=warm, timeout_s=2.0).run(image)
    assert idle.status == "timeout" and not idle.starved, idle.message


#: Busy in 16 processes pinned to one CPU: they wait for each other more than for others.
SELF_BUSY = PINNED_BUSY.replace("while True:", "for _ in range(15):\n    if os.fork() == 0:\n"
                                "        break\nwhile True:")
NICE_BUSY = PINNED_BUSY.replace("while True:", "os.nice(19)\nwhile True:")


@pytest.mark.integration
@pytest.mark.parametrize("script", [SELF_BUSY, NICE_BUSY], ids=["own-threads", "own-nice"])
def test_a_run_that_makes_itself_wait_is_its_own_timeout(script, toy, tmp_path, run_tmp):
    # a team cannot pass its own hang off as the machine's (a harness error stops a grade):
    # waiting for its own processes, or behind everything after lowering its own priority
    path = tmp_path / "self.py"
    path.write_text(script)
    image = sorted((toy / "images").iterdir())[0]
    burners = _burners(2) if script is NICE_BUSY else []
    try:
        pred = _pipe(path, "none", warm=False, timeout_s=2.0, max_procs=64).run(image)
    finally:
        for b in burners:
            b.kill()
            b.wait()
    assert pred.status == "timeout" and not pred.starved, pred.message


SHADOW_NUMPY = "FAKE = True\n"
USES_NUMPY = textwrap.dedent("""\
    import numpy
    fake = getattr(numpy, "FAKE", False)
    open("obstacles.txt", "w").write(f"Obstacles: {7 if fake else 1}\\nArea: 0\\n")
""")


@pytest.mark.integration
@pytest.mark.parametrize("sandbox", [pytest.param("bwrap", marks=needs_bwrap), "none"])
def test_a_submission_module_shadowing_a_preload_runs_as_cold_does(sandbox, toy, tmp_path,
                                                                   run_tmp, capfd):
    team = tmp_path / "team"
    team.mkdir()
    (team / "numpy.py").write_text(SHADOW_NUMPY)
    (team / "map.py").write_text(USES_NUMPY)
    image = sorted((toy / "images").iterdir())[0]
    cold = _pipe(team / "map.py", sandbox, warm=False).run(image)
    warm = _pipe(team / "map.py", sandbox).run(image)
    assert cold.count == 7, (cold.message, cold.stderr)  # the team's own numpy, cold
    assert (warm.status, warm.count) == (cold.status, cold.count), (warm.message, warm.stderr)
    assert "numpy" in capfd.readouterr().err  # said once: this command runs cold


CRASHES = textwrap.dedent("""\
    def detect():
        raise ValueError("no markers here")


    detect()
""")


@pytest.mark.integration
@pytest.mark.parametrize("sandbox", [pytest.param("bwrap", marks=needs_bwrap), "none"])
def test_a_warm_crash_prints_the_scripts_traceback_alone(sandbox, toy, tmp_path, run_tmp):
    script = tmp_path / "crash.py"
    script.write_text(CRASHES)
    image = sorted((toy / "images").iterdir())[0]
    cold = _pipe(script, sandbox, warm=False).run(image)
    warm = _pipe(script, sandbox).run(image)
    assert cold.status == warm.status == "crash"
    assert warm.stderr == cold.stderr, (warm.stderr, cold.stderr)
    assert warm.stderr.count("File ") == 2  # <module> and detect: the script's frames only


SLOW_MARKED = textwrap.dedent("""\
    import os, sys, time
    from pathlib import Path
    Path(os.environ["STARTED_AT"]).touch()
    time.sleep(600)
""")


@pytest.mark.integration
@needs_bwrap
@needs_cgroup
def test_a_sigkilled_warm_command_leaves_nothing_the_next_sweep_misses(toy, tmp_path):
    script = tmp_path / "slow.py"
    script.write_text(HANG)
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    env = {**os.environ, "TMPDIR": str(tmpdir)}
    argv = [PY, "-m", "arenabench", "eval", str(toy), "--cmd",
            f"{PY} {script} --image {{image}}", "--sandbox", "bwrap", "--no-progress",
            "--phase-check", "off", "--workers", "1"]
    proc = subprocess.Popen(argv, env=env, start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)

    def runs_held():  # the warm server is up: its cgroup holds its runs' (standbys') cgroups
        return [g for g in _warm_cgroups_of(proc.pid)
                if any(p.is_dir() for p in Path(CGROUP, g).iterdir())]

    try:
        assert wait_for(runs_held, timeout=300), "no warm server started"
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    warm_dirs = [p for p in tmpdir.iterdir() if p.name.startswith("arenabench-warm-")
                 and (p / OWNER_FILE).read_text() == str(proc.pid)]  # a random name
    assert warm_dirs and _warm_cgroups_of(proc.pid), list(tmpdir.iterdir())
    removed = sweep_stale_runs(tmpdir=str(tmpdir), cgroup_parent=CGROUP, force=True)
    assert not any(p.exists() for p in warm_dirs), removed
    assert _warm_cgroups_of(proc.pid) == [], removed


def test_the_preflight_folder_of_a_killed_command_is_swept(tmp_path):
    dead = subprocess.run([PY, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, check=True)
    pid = int(dead.stdout)
    left = tmp_path / f"arenabench-preflight-{pid}-abcd"
    (left / "probe").mkdir(parents=True)
    mine = tmp_path / f"arenabench-preflight-{os.getpid()}-efgh"
    mine.mkdir()
    removed = sweep_stale_runs(tmpdir=str(tmp_path), force=True)
    assert not left.exists() and str(left) in removed
    assert mine.exists()  # a live owner's folder is never touched


def test_a_warm_folder_is_swept_by_the_pid_in_its_owner_file(tmp_path):
    dead = subprocess.run([PY, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, check=True)
    left = tmp_path / "arenabench-warm-abcd1234"
    left.mkdir()
    (left / OWNER_FILE).write_text(dead.stdout.strip())
    mine = Path(make_warm_dir_in(tmp_path))
    assert str(os.getpid()) not in mine.name  # a random name: it says nothing of its owner
    unowned = tmp_path / "arenabench-warm-efgh5678"  # its harness died before the file
    unowned.mkdir()
    earlier = tmp_path / f"arenabench-warm-{dead.stdout.strip()}-ijkl"  # an earlier version's
    earlier.mkdir()
    removed = sweep_stale_runs(tmpdir=str(tmp_path), force=True)
    assert not left.exists() and str(left) in removed
    assert not earlier.exists() and str(earlier) in removed
    assert mine.exists() and unowned.exists()  # alive; too young to be taken for stale
    old = time.time() - OWNERLESS_GRACE_S - 5
    os.utime(unowned, (old, old))
    assert str(unowned) in sweep_stale_runs(tmpdir=str(tmp_path), force=True)
    assert mine.exists()


def make_warm_dir_in(folder: Path) -> str:
    saved = tempfile.tempdir
    tempfile.tempdir = str(folder)
    try:
        return make_warm_dir()
    finally:
        tempfile.tempdir = saved


DETACHES = textwrap.dedent(f"""\
    import os, subprocess, sys


    def detect(image):
        if os.fork() == 0:  # a detached grandchild: its own session, its parent gone
            os.setsid()
            if os.fork() == 0:
                os.execv(sys.executable, [sys.executable, "-c", "import time; time.sleep(600)",
                                          {BURNER!r} + "-detached"])
            os._exit(0)
        return {{"count": 0, "area": 0.0}}
""")


@pytest.mark.integration
def test_an_in_process_pipelines_detached_child_dies_with_eval(toy, tmp_path):
    (tmp_path / "detaching.py").write_text(DETACHES)
    result = run_cli("eval", str(toy), "--pipeline", "detaching:detect", "--no-progress",
                     "--limit", "2", "--workers", "1", "--phase-check", "off", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert wait_for(lambda: not processes_with(BURNER + "-detached"), timeout=30), \
        processes_with(BURNER + "-detached")


ANSWERS = "open('obstacles.txt', 'w').write('Obstacles: 0\\nArea: 0\\n')\n"


def _tiny_tmpdir(tmp_path: Path) -> tuple[list[str], Path]:
    """A prefix running a command with TMPDIR on a tmpfs too small for any image's copy."""
    unshare = shutil.which("unshare")
    if os.getuid() != 0 or unshare is None:
        pytest.skip("needs root and 'unshare --mount' for a full TMPDIR")
    tiny = tmp_path / "tiny"
    tiny.mkdir()
    return [unshare, "--mount", "--propagation", "private", "sh", "-c",
            f'mount -t tmpfs -o size=4k none {tiny} && exec "$@"', "sh"], tiny


@pytest.mark.integration
@pytest.mark.parametrize("warm", [True, False])
def test_a_full_tmpdir_is_the_harness_failure_never_the_scripts(warm, toy, tmp_path):
    prefix, tiny = _tiny_tmpdir(tmp_path)
    script = tmp_path / "answers.py"
    script.write_text(ANSWERS)
    out = tmp_path / "out"
    argv = [*prefix, PY, "-m", "arenabench", "eval", str(toy), "--cmd",
            f"{PY} {script} --image {{image}}", "--sandbox", "none", "--no-progress",
            "--phase-check", "off", "--workers", "1", "--out", str(out),
            *([] if warm else ["--no-warm"])]
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=600,
                          env={**os.environ, "TMPDIR": str(tiny)})
    assert proc.returncode == 4, (proc.returncode, proc.stderr[-2000:])
    assert "the harness could not run an image" in proc.stderr and "Traceback" not in proc.stderr
    doc = json.loads((out / "report.json").read_text())
    assert doc["complete"] is False
    assert all(r["category"] != "crash" for r in doc["images"]), doc["images"]


def test_a_full_tmpdir_stops_a_grade_without_scoring_any_team(toy, tmp_path):
    prefix, tiny = _tiny_tmpdir(tmp_path)
    subs = tmp_path / "subs"
    for name in ("a", "b"):
        (subs / name).mkdir(parents=True)
        (subs / name / "map.py").write_text(ANSWERS)
    out = tmp_path / "out"
    argv = [*prefix, PY, "-m", "arenabench", "grade", str(toy), str(subs), "--out", str(out),
            "--cmd", f"{PY} {{submission}}/map.py --image {{image}}", "--sandbox", "none",
            "--allow-guessable-seed", "--no-progress", "--phase-check", "off",
            "--max-procs", "0"]
    proc = subprocess.run(argv, capture_output=True, text=True, timeout=600,
                          env={**os.environ, "TMPDIR": str(tiny)})
    assert proc.returncode == 4, (proc.returncode, proc.stderr[-2000:])
    assert "the harness could not run an image" in proc.stderr and "Traceback" not in proc.stderr
    assert not list(out.glob("teams/*/report.json"))  # no team graded on a broken harness
