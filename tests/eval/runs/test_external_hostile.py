"""Hostile external pipelines (tests/pipelines/hostile/), run for real: every one contained and
categorised, the run finishing, nothing left behind. With bubblewrap (real bwrap) where it
works here, and with ``--sandbox none`` for what must hold without it."""

import json
import os
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import toy_arena
from hostile_util import processes_with, wait_for
from marks import integration_but
from paths import TESTS

from arenabench.eval.evaluation import EvaluationFailed, evaluate
from arenabench.eval.runs import CommandPipeline, RunContext
from arenabench.eval.runs.limits import RunLimits, RunSettings
from arenabench.eval.runs.sandbox import bwrap_problem, pids_cgroup_parent

PIPES = TESTS / "pipelines"
HOSTILE = PIPES / "hostile"

PY = sys.executable
needs_bwrap = pytest.mark.skipif(bwrap_problem() is not None, reason=str(bwrap_problem()))
SANDBOXES = [pytest.param("bwrap", marks=needs_bwrap), "none"]


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toy") / "toy set", n=4, seed=5)


def _pipe(script, sandbox, *, env=None, **limits):
    settings = RunSettings(
        limits=RunLimits(**{"timeout_s": 30.0, **limits}), sandbox=sandbox, env=env or {}
    )
    return CommandPipeline(f"{PY} {HOSTILE / script} --image {{image}}", settings=settings)


def _one(script, sandbox, toy, **kw):
    report = evaluate(_pipe(script, sandbox, **kw), toy, workers=2, limit=2)
    return report.images


@needs_bwrap
def test_snooping_finds_no_dataset_under_bwrap(toy, run_tmp):
    images = _one("snoop.py", "bwrap", toy, env={"TARGET": str(toy)})
    for r in images:
        seen = json.loads(r.prediction.stdout.strip().splitlines()[-1])
        assert seen["found"] == [], seen["found"]
        assert seen["cwd"] == "/sandbox" and seen["cwd_files"] == ["image.png"]
        assert seen["argv"][-1] == "/sandbox/image.png"
        assert seen["target"] == ["<No such file or directory>"]
        assert seen["suspicious"] == []
        assert r.prediction.status == "ok"


@needs_bwrap
def test_a_submission_under_tmp_runs_and_still_sees_no_dataset(toy, run_tmp, tmp_path):
    import shutil

    team = tmp_path / "team folder"
    team.mkdir()
    for name in ("snoop.py", "common.py"):
        shutil.copy(HOSTILE / name, team / name)
    pipe = CommandPipeline(
        f"{PY} snoop.py --image {{image}}", settings=RunSettings(sandbox="bwrap",
                                                                  env={"TARGET": str(toy)}),
        base_dir=str(team),
    )
    for r in evaluate(pipe, toy, workers=2, limit=2).images:
        assert r.prediction.status == "ok", (r.prediction.message, r.prediction.stderr)
        seen = json.loads(r.prediction.stdout.strip().splitlines()[-1])
        assert seen["found"] == [] and seen["suspicious"] == []
        assert seen["target"] == ["<No such file or directory>"]


@pytest.mark.integration
@pytest.mark.parametrize("sandbox", SANDBOXES)
def test_private_directory_and_scrubbed_environment(sandbox, toy, run_tmp, monkeypatch):
    monkeypatch.setenv("SECRET_TOKEN", "s3cr3t")
    pipe = CommandPipeline(
        f"{PY} {HOSTILE / 'snoop.py'} --image {{image}}",
        settings=RunSettings(sandbox=sandbox, image_name="frame.png", env={"EXTRA": "1"}),
    )
    for r in evaluate(pipe, toy, workers=2, limit=2).images:
        seen = json.loads(r.prediction.stdout.strip().splitlines()[-1])
        assert set(seen["env"]) <= {"PATH", "HOME", "LANG", "LC_ALL", "TMPDIR", "EXTRA", "PWD"}
        assert seen["env"]["EXTRA"] == "1" and seen["env"]["HOME"] == seen["cwd"]
        assert seen["cwd_files"] == ["frame.png"]
        assert os.path.basename(seen["argv"][-1]) == "frame.png"
        assert str(toy) not in json.dumps([seen["argv"], seen["env"]])


@pytest.mark.integration
@needs_bwrap
def test_loopback_connection_fails_under_bwrap(toy, run_tmp):
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    server.settimeout(0.5)
    port = server.getsockname()[1]
    try:
        images = _one("network.py", "bwrap", toy, env={"PORT": str(port)})
        with pytest.raises(TimeoutError):
            server.accept()
    finally:
        server.close()
    for r in images:
        assert r.category == "crash"
        assert "connect failed" in r.prediction.stderr


@needs_bwrap
def test_writes_outside_the_private_directory_fail_under_bwrap(toy, run_tmp, tmp_path):
    target = tmp_path / "outside.txt"
    images = _one("escape_write.py", "bwrap", toy, env={"TARGET": str(target)})
    assert not target.exists()
    assert not (HOSTILE / "escaped.txt").exists()
    for r in images:
        assert "WROTE" not in r.prediction.stdout
        assert r.prediction.stdout.count("refused") == 3


@pytest.mark.parametrize("sandbox", integration_but(SANDBOXES, "bwrap"))
def test_detached_daemons_are_gone_and_do_not_hold_the_run(sandbox, toy, run_tmp):
    marker = f"daemon-marker-{os.getpid()}-{sandbox}"
    images = _one("daemon.py", sandbox, toy, env={"MARKER": marker})
    for r in images:
        # they hold stdout open, yet the run ends with its main process
        assert r.prediction.status == "ok", r.prediction.message
        assert r.prediction.latency_ms < 30_000
        assert "answered" in r.prediction.stdout
    assert processes_with(marker) == []


@pytest.mark.parametrize("sandbox", integration_but(SANDBOXES, "none"))
def test_memory_past_the_limit_is_a_limit(sandbox, toy, run_tmp):
    images = _one("memory.py", sandbox, toy, env={"MB": "1024"}, memory_bytes=256 * 1024**2)
    for r in images:
        assert r.category == "limit", (r.prediction.message, r.prediction.stderr)
        assert r.prediction.message.startswith("memory limit (--memory-limit 256M)")


@pytest.mark.parametrize("sandbox", integration_but(SANDBOXES, "none"))
def test_fork_bomb_past_max_procs_is_a_limit(sandbox, toy, run_tmp):
    if pids_cgroup_parent() is None and os.getuid() == 0:
        pytest.skip("root without a writable pids cgroup: --max-procs is not enforceable")
    marker = str(HOSTILE / "forkbomb.py")
    images = _one("forkbomb.py", sandbox, toy, max_procs=16)
    for r in images:
        assert r.category == "limit", (r.prediction.message, r.prediction.stderr)
        assert r.prediction.message.startswith("process limit (--max-procs 16)")
        assert "forked 500" not in r.prediction.stdout
    assert processes_with(marker) == []
    # the machine still forks
    assert subprocess.run(["true"]).returncode == 0


def _rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return float(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


@pytest.mark.integration
def test_100_mb_of_stdout_keeps_a_bounded_tail_and_flat_memory(toy, run_tmp):
    peak = [_rss_mb()]
    base = peak[0]
    done = threading.Event()

    def sample():
        while not done.is_set():
            peak[0] = max(peak[0], _rss_mb())
            done.wait(0.02)

    t = threading.Thread(target=sample)
    t.start()
    try:
        images = _one("bigprint.py", "auto", toy, env={"MB": "100"}, max_output=64 * 1024)
    finally:
        done.set()
        t.join()
    for r in images:
        assert r.prediction.status == "ok", r.prediction.message
        assert r.prediction.stdout.endswith("the end\n")
        assert len(r.prediction.stdout) <= 2100
    assert peak[0] - base < 40, f"harness RSS grew by {peak[0] - base:.0f} MB"


@pytest.mark.integration
@pytest.mark.parametrize("sandbox", SANDBOXES)
def test_file_size_limit_and_oversized_answer(sandbox, toy, run_tmp):
    big = _one("bigfile.py", sandbox, toy, env={"MB": "64"}, max_file_size=8 * 1024**2)
    for r in big:
        assert r.category == "limit", (r.prediction.message, r.prediction.stderr)
        assert r.prediction.message.startswith("file size limit (--max-file-size 8M)")
    huge_answer = _one("bigfile.py", sandbox, toy, env={"MB": "2", "NAME": "obstacles.txt"})
    for r in huge_answer:
        assert r.category == "bad_output"
        assert "more than the 65536 allowed" in r.prediction.message


@pytest.mark.parametrize("sandbox", SANDBOXES)
def test_sigxfsz_of_a_native_writer_is_a_limit(sandbox, toy, run_tmp):
    settings = RunSettings(limits=RunLimits(max_file_size=1024**2), sandbox=sandbox)
    pipe = CommandPipeline("dd if=/dev/zero of=big.bin bs=64k count=64", settings=settings)
    for r in evaluate(pipe, toy, workers=2, limit=2).images:
        assert r.category == "limit", (r.prediction.message, r.prediction.stderr)
        assert r.prediction.message.startswith("file size limit (--max-file-size 1M)")


def _own_hang_on(tmp_path: Path) -> Path:
    """A copy of ``hang_on.py`` at a path of this test's own: what is left of its runs is
    told apart from another test's hanging runs (``pytest -n``) by its command line."""
    folder = tmp_path / "hang_on"
    folder.mkdir()
    for name in ("hang_on.py", "common.py"):
        (folder / name).write_bytes((HOSTILE / name).read_bytes())
    return folder / "hang_on.py"


def _eval_cmd(toy, out, tmpdir, *, script, hang, marker, workers=1, sandbox="auto"):
    env = {**os.environ, "TMPDIR": str(tmpdir)}
    argv = [
        PY, "-m", "arenabench", "eval", str(toy), "--cmd",
        f"{PY} {script} --image {{image}}", "--env", f"HANG={hang}",
        "--env", f"MARKER={marker}", "--workers", str(workers), "--no-progress",
        "--formats", "json", "--out", str(out), "--timeout", "120", "--sandbox", sandbox,
    ]  # fmt: skip
    return subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _sha(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.integration
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_eval_with_a_partial_report(signum, toy, tmp_path):
    marker = f"signal-marker-{os.getpid()}-{int(signum)}"
    children = f"{marker}:child"
    second = sorted((toy / "images").iterdir())[1]
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    script = _own_hang_on(tmp_path)
    proc = _eval_cmd(toy, tmp_path / "out", tmpdir, script=script, hang=_sha(second),
                     marker=marker)
    try:
        assert wait_for(lambda: processes_with(children), timeout=60), "the pipeline never hung"
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=15)
    finally:
        proc.kill()
    assert proc.returncode == 128 + signum, err
    assert b"Traceback" not in err
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["complete"] is False and report["n_done"] == 1
    assert [i["id"] for i in report["images"]] == ["000000"]
    assert wait_for(lambda: not processes_with(children), timeout=5)
    assert processes_with(str(script)) == []
    assert processes_with(str(tmpdir)) == []  # launchers
    assert list(tmpdir.iterdir()) == []


@pytest.mark.integration
def test_sigkill_of_the_harness_leaves_no_processes_or_directories(toy, tmp_path):
    marker = f"sigkill-marker-{os.getpid()}"
    children = f"{marker}:child"
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    script = _own_hang_on(tmp_path)
    proc = _eval_cmd(toy, tmp_path / "out", tmpdir, script=script, hang="all", marker=marker,
                     workers=2)
    try:
        assert wait_for(lambda: len(processes_with(children)) >= 4, timeout=60)
        proc.kill()
        proc.wait()
    finally:
        proc.kill()
    assert wait_for(lambda: not processes_with(children), timeout=10), processes_with(children)
    assert wait_for(lambda: not processes_with(str(script)), timeout=10)
    assert wait_for(lambda: not processes_with(str(tmpdir)), timeout=10)  # launchers
    assert wait_for(lambda: not list(tmpdir.iterdir()), timeout=10), list(tmpdir.iterdir())


@pytest.mark.parametrize(
    "cmd, message",
    [
        ("no-such-pipeline-xyz --image {image}", "'no-such-pipeline-xyz' not found on PATH"),
        ("./missing/map.py --image {image}", "'./missing/map.py' does not exist"),
    ],
)
def test_missing_executable_is_refused_up_front(cmd, message, toy, capsys):
    from arenabench.eval.commands.eval import main

    assert main([str(toy), "--cmd", cmd, "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]


def test_sandbox_bwrap_where_it_does_not_work_is_a_usage_error(toy, capsys, monkeypatch):
    from arenabench.eval.commands.eval import main
    from arenabench.eval.runs import sandbox

    monkeypatch.setenv("PATH", str(Path(PY).parent))  # no bwrap on this PATH
    sandbox.forget_probes()
    try:
        rc = main([str(toy), "--cmd", f"{PY} {__file__} {{image}}", "--sandbox", "bwrap"])
    finally:
        sandbox.forget_probes()
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bubblewrap (bwrap) is not installed" in err[0]


@pytest.mark.integration
def test_sandbox_auto_without_bwrap_warns_once_and_still_contains(
    toy, run_tmp, monkeypatch, capsys
):
    from arenabench.eval.runs import sandbox

    monkeypatch.setenv("PATH", str(Path(PY).parent))  # no bwrap on this PATH
    sandbox.forget_probes()
    try:
        pipes = [_pipe("snoop.py", "auto") for _ in range(3)]
    finally:
        sandbox.forget_probes()
    assert {p.sandbox for p in pipes} == {"none"}
    err = capsys.readouterr().err.strip().splitlines()
    assert len([line for line in err if "WITHOUT a sandbox" in line]) == 1
    seen = json.loads(pipes[0].run(sorted((toy / "images").iterdir())[0]).stdout.splitlines()[-1])
    assert seen["cwd_files"] == ["image.png"] and seen["env"]["HOME"] == seen["cwd"]


@pytest.mark.integration
def test_limit_is_a_failure_category_everywhere(toy, run_tmp):
    from arenabench.eval.scoring.results import CATEGORIES, STATUSES
    from arenabench.eval.scoring.thresholds import check_thresholds, parse_thresholds

    assert "limit" in CATEGORIES and "limit" in STATUSES
    report = evaluate(_pipe("memory.py", "none", env={"MB": "1024"}, memory_bytes=256 * 1024**2),
                      toy, workers=2, limit=2)
    assert report.summary.failures["limit"] == 2
    reasons = check_thresholds(report.summary, parse_thresholds(["failures.limit=0"]))
    assert reasons == ["failures.limit 2 > 0 (maximum)"]


@needs_bwrap
def test_a_command_on_path_sees_its_installation_prefix(toy, run_tmp, tmp_path, monkeypatch):
    """Like a pyenv shim or a conda python: bin/TOOL needs files beside its bin/ folder."""
    prefix = tmp_path / "prefix"
    (prefix / "bin").mkdir(parents=True)
    (prefix / "libexec").mkdir()
    real = prefix / "libexec" / "tool-real"
    real.write_text("#!/bin/sh\nprintf 'Aruco ID: [80, 85, 90, 95]\\nObstacles: 1\\n"
                    "Area: 10.0\\n' > obstacles.txt\n")
    shim = prefix / "bin" / "tool"
    shim.write_text('#!/bin/sh\nexec "$(dirname "$0")/../libexec/tool-real" "$@"\n')
    for f in (real, shim):
        f.chmod(0o755)
    monkeypatch.setenv("PATH", f"{prefix / 'bin'}{os.pathsep}{os.environ['PATH']}")
    pipe = CommandPipeline("tool --image {image}", settings=RunSettings(sandbox="bwrap"))
    for r in evaluate(pipe, toy, workers=2, limit=2).images:
        assert r.prediction.status == "ok", (r.prediction.message, r.prediction.stderr)
        assert (r.prediction.count, r.prediction.area) == (1, 10.0)


@pytest.mark.parametrize("sandbox", SANDBOXES)
def test_obstacles_txt_that_is_a_directory_is_bad_output(sandbox, toy, run_tmp):
    settings = RunSettings(limits=RunLimits(timeout_s=30.0), sandbox=sandbox)
    pipe = CommandPipeline(f"{PY} -c \"import os; os.mkdir('obstacles.txt')\" {{image}}",
                           settings=settings)
    images = evaluate(pipe, toy, workers=1, limit=1).images
    assert [(r.category, r.prediction.message) for r in images] == [
        ("bad_output", "obstacles.txt is a directory")]


@pytest.mark.parametrize("sandbox", SANDBOXES)
def test_long_and_empty_arguments_reach_the_command_as_given(sandbox, toy, run_tmp):
    long_arg = "x" * 300
    check = ("import sys, os; a = sys.argv[1:]; "
             f"ok = a[0] == {long_arg!r} and a[1] == '' and os.path.isfile(a[2]); "
             "open('obstacles.txt', 'w').write('Obstacles: 0\\nArea: 0.0\\n') if ok "
             "else sys.exit('args: ' + repr(a)[:200])")
    settings = RunSettings(limits=RunLimits(timeout_s=30.0), sandbox=sandbox)
    pipe = CommandPipeline(f"{PY} -c \"{check}\" {long_arg} '' {{image}}", settings=settings)
    images = evaluate(pipe, toy, workers=1, limit=1).images
    assert images[0].category in (None, "wrong_count", "area_off"), images[0].prediction.message
    argv = pipe.argv(Path("/x/image.png"))
    assert argv[3:5] == [long_arg, ""], argv  # never the working directory's path
    assert os.getcwd() not in pipe.command.visible


def test_stale_run_dirs_and_cgroups_of_dead_owners_are_swept(tmp_path):
    from arenabench.eval.runs.stale import RUN_PREFIX, sweep_stale_runs

    dead = subprocess.Popen([PY, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f"{RUN_PREFIX}{dead.pid}-abc"
    (stale / "work").mkdir(parents=True)
    (stale / "work" / "obstacles.txt").write_text("x")
    live = tmp_path / f"{RUN_PREFIX}1-abc"  # pid 1 is alive
    live.mkdir()
    other = tmp_path / "arenabench-run-notapid"
    other.mkdir()
    parent = pids_cgroup_parent()
    group = None
    if parent is not None:
        group = Path(parent, f"{RUN_PREFIX}{dead.pid}")
        group.mkdir()
    removed = sweep_stale_runs(tmpdir=str(tmp_path), cgroup_parent=parent, force=True)
    assert str(stale) in removed and not stale.exists()
    assert live.is_dir() and other.is_dir()
    if group is not None:
        assert str(group) in removed and not group.exists()


@pytest.mark.integration
def test_sigkill_of_the_whole_group_is_swept_by_the_next_run(toy, tmp_path):
    marker = f"killpg-marker-{os.getpid()}"
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    env = {**os.environ, "TMPDIR": str(tmpdir)}
    argv = [PY, "-m", "arenabench", "eval", str(toy), "--cmd",
            f"{PY} {HOSTILE / 'hang_on.py'} --image {{image}}", "--env", "HANG=all",
            "--env", f"MARKER={marker}", "--workers", "2", "--no-progress", "--sandbox",
            "none", "--timeout", "120"]
    proc = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        assert wait_for(lambda: len(processes_with(f"{marker}:child")) >= 2, timeout=60)
        os.killpg(proc.pid, signal.SIGKILL)  # harness and launchers at once
        proc.wait()
    finally:
        proc.kill()
    left = list(tmpdir.iterdir())
    assert left, "nothing left behind to sweep (the case is not reproduced)"
    argv2 = [PY, "-m", "arenabench", "eval", str(toy), "--cmd",
             f"{PY} -m arenabench.detect --image {{image}}", "--limit", "1", "--no-progress",
             "--sandbox", "none"]
    second = subprocess.run(argv2, env=env, capture_output=True, text=True, timeout=120)
    try:
        assert second.returncode in (0, 1), second.stderr
        assert list(tmpdir.iterdir()) == [], list(tmpdir.iterdir())
        if pids_cgroup_parent() is not None:  # the dead launchers' cgroups held the orphans
            assert wait_for(lambda: not processes_with(f"{marker}:child"), timeout=10), [
                (p, Path(f"/proc/{p}/cgroup").read_text()) for p in
                processes_with(f"{marker}:child")]
    finally:
        for pid in processes_with(f"{marker}:child"):
            os.kill(pid, signal.SIGKILL)


def test_pids_cgroup_probe_is_thread_safe(monkeypatch):
    from concurrent.futures import ThreadPoolExecutor

    from arenabench.eval.runs import sandbox

    first = sandbox.pids_cgroup_parent()
    if first is None:
        pytest.skip("no writable pids cgroup here")
    for _ in range(5):  # grade constructs its pipelines from many threads at once
        sandbox.forget_probes()
        with ThreadPoolExecutor(16) as pool:
            found = list(pool.map(lambda _: sandbox.pids_cgroup_parent(), range(32)))
        assert set(found) == {first}
    assert not [p for p in os.listdir(first) if p.startswith(f"arenabench-probe-{os.getpid()}")]


@pytest.mark.parametrize("sandbox", SANDBOXES)
@pytest.mark.integration
def test_ptrace_of_the_launcher_is_refused_and_the_timeout_holds(sandbox, toy, run_tmp):
    import time

    start = time.monotonic()
    images = _one("ptrace_parent.py", sandbox, toy, timeout_s=2.0)
    assert time.monotonic() - start < 20
    for r in images:
        assert r.category == "timeout", r.prediction.message
        if sandbox == "none":  # under bwrap its parent is the sandbox's own init: harmless
            assert "attach -1" in r.prediction.stdout, r.prediction.stdout


@pytest.mark.integration
@pytest.mark.parametrize("target", ["harness", "group"])
def test_sigterm_with_a_command_that_ignores_it_is_not_exit_0(toy, tmp_path, target):
    script = tmp_path / "ignore_term.py"
    started = tmp_path / "started.pid"  # the command's pid (warm or cold: its cmdline differs)
    script.write_text("import os, signal, time\nsignal.signal(signal.SIGTERM, signal.SIG_IGN)\n"
                      f"open({str(started)!r}, 'w').write(str(os.getpid()))\n"
                      "time.sleep(60)\n")
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [PY, "-m", "arenabench", "eval", str(toy), "--cmd", f"{PY} {script} {{image}}",
         "--sandbox", "none", "--workers", "1", "--no-progress", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        assert wait_for(lambda: started.exists() and started.read_text(), timeout=60)
        pid = int(started.read_text())
        if target == "group":
            os.killpg(proc.pid, signal.SIGTERM)
        else:
            proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 143, err
    assert "Traceback" not in err

    def gone() -> bool:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"

    assert wait_for(gone, timeout=10)


@pytest.mark.integration
@pytest.mark.parametrize("warm", [False, True])
def test_a_run_whose_pids_cgroup_cannot_be_made_is_not_run(warm, toy, run_tmp, tmp_path):
    """The pids cgroup parent was probed writable but the run's own cgroup cannot be made (here:
    the parent vanished): the command is not run at all, rather than run without --max-procs."""
    ran = tmp_path / "ran"
    script = tmp_path / "map.py"
    script.write_text(f"open({str(ran)!r}, 'w').close()\n")
    settings = RunSettings(limits=RunLimits(timeout_s=30.0, max_procs=16), sandbox="none",
                           warm=warm)
    with RunContext(cgroup_parent=str(tmp_path / "no such cgroup")) as runs:
        pipe = CommandPipeline(f"{PY} {script} --image {{image}}", settings=settings,
                               context=runs)
        with pytest.raises(EvaluationFailed) as failed:  # the harness's failure: never scored
            evaluate(pipe, toy, workers=1, limit=1)
    assert "cannot create the run's pids cgroup" in str(failed.value)
    assert "--max-procs 16 cannot be enforced" in str(failed.value)
    assert failed.value.report.images == ()
    assert not ran.exists()
