"""The warm interpreter of Python commands (eval/runs/warm_client.py, warm_server.py), run for
real: with bubblewrap where it works here and with ``--sandbox none``."""

from __future__ import annotations

import hashlib
import json
import os
import sys
from dataclasses import dataclass, field, fields
from pathlib import Path

import pytest
import toy_arena  # tests/pipelines (pytest's pythonpath)
from marks import integration_but
from paths import TESTS

from arenabench.eval.evaluation import evaluate
from arenabench.eval.runs import CommandPipeline
from arenabench.eval.runs.command import Command
from arenabench.eval.runs.limits import RunLimits, RunSettings
from arenabench.eval.runs.sandbox import bwrap_problem, pids_cgroup_parent
from arenabench.eval.runs.warm_target import WarmTarget, warm_target

PIPES = TESTS / "pipelines"
PROBE = PIPES / "warm_probe.py"
PY = sys.executable

needs_bwrap = pytest.mark.skipif(bwrap_problem() is not None, reason=str(bwrap_problem()))
SANDBOXES = [pytest.param("bwrap", marks=needs_bwrap), "none"]


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toy") / "toy", n=4, seed=3)


def _probe(sandbox, *, warm=True, env=None, context=None, **limits):
    settings = RunSettings(limits=RunLimits(**{"timeout_s": 30.0, **limits}), sandbox=sandbox,
                           warm=warm, env=env or {})
    return CommandPipeline(f"{PY} {PROBE} --image {{image}}", settings=settings,
                           context=context)


def _seen(pred):
    return json.loads(pred.stdout.strip().splitlines()[-1])


def test_which_commands_run_warm(tmp_path):
    script = tmp_path / "map.py"
    script.write_text("")
    s = str(script)
    assert warm_target(["{python}", s, "--image", "{image}"]) == WarmTarget(script=s)
    assert warm_target(["/usr/bin/python3", s]) == WarmTarget(script=s)
    assert warm_target(["/venv/bin/python3.12", s]) == WarmTarget(script=s)
    assert warm_target(["python", "-m", "pkg.mod", "x"]) == WarmTarget(module="pkg.mod")
    for cold in (["python", "-u", s], ["python", "-c", "pass"], ["bash", s],
                 ["python", str(tmp_path / "missing.py")], ["./map", "--image", "{image}"],
                 ["python", "{image}"], ["python"]):
        assert warm_target(cold) is None, cold
    with CommandPipeline(f"{PY} {PROBE}", settings=RunSettings(warm=False)) as pipe:
        assert pipe.command.warm is None


@pytest.mark.integration
@pytest.mark.parametrize("sandbox", SANDBOXES)
def test_each_image_is_a_fresh_run_of_the_script_as_main(sandbox, toy, run_tmp):
    cold = {r.id: r for r in evaluate(_probe(sandbox, warm=False), toy, workers=1).images}
    warm = {r.id: r for r in evaluate(_probe(sandbox), toy, workers=1).images}
    assert set(cold) == set(warm) and len(warm) == 4
    for ident, w in warm.items():
        c = cold[ident]
        assert (w.prediction.status, w.prediction.count, w.prediction.area) == (
            c.prediction.status, c.prediction.count, c.prediction.area)
        ws, cs = _seen(w.prediction), _seen(c.prediction)
        assert ws["preloaded"] == ["cv2", "numpy"] and cs["preloaded"] == []
        assert not any(ws["marks"].values()) and not any(cs["marks"].values()), ws["marks"]
        assert len(ws["marks"]) == len(cs["marks"]) == (3 if sandbox == "bwrap" else 2)
        for key in ("name", "cwd_files", "path0", "env"):
            assert ws[key] == cs[key], key
        if sandbox == "bwrap":
            assert ws["argv"] == cs["argv"] and ws["cwd"] == cs["cwd"] == "/sandbox"
            # the server's folders and the huge-page settings its glibc read: empty here
            assert ws["hidden"] in ([[], [], []], [[], None, []], [[], [], None],
                                    [[], None, None])
            assert cs["hidden"] == [None, None, None]
        else:
            assert Path(ws["argv"][-1]).name == Path(cs["argv"][-1]).name == "image.png"


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.mark.parametrize("sandbox", integration_but(SANDBOXES, "bwrap"))
@pytest.mark.parametrize("mode, category, limits", [
    pytest.param("hang", "timeout", {"timeout_s": 3.0}, marks=pytest.mark.integration),
    ("memory", "limit", {"memory_bytes": 1024**3}),
    pytest.param("forkbomb", "limit", {"max_procs": 16}, marks=pytest.mark.integration),
])
def test_a_misbehaving_run_ends_alone_and_the_server_goes_on(sandbox, mode, category, limits,
                                                             toy, runs):
    if mode == "forkbomb" and pids_cgroup_parent() is None and os.getuid() == 0:
        pytest.skip("root without a writable pids cgroup: --max-procs is not enforceable")
    images = sorted((toy / "images").iterdir())
    pipe = _probe(sandbox, env={"PROBE_BAD": _sha(images[1]), "PROBE_MODE": mode},
                  context=runs, **limits)
    first = pipe.run(images[0])
    assert first.status == "ok" and _seen(first)["preloaded"] == ["cv2", "numpy"]
    (server,) = runs.servers.servers()
    bad = pipe.run(images[1])
    assert bad.status == category, (bad.message, bad.stderr)
    for image in images[2:]:
        after = pipe.run(image)
        assert after.status == "ok", (after.message, after.stderr)
        assert _seen(after)["preloaded"] == ["cv2", "numpy"]
    assert runs.servers.servers() == [server] and not server.dead


_COUNT_FORKS = """
import os, signal, time
kids = []
for _ in range(64):
    try:
        pid = os.fork()
    except OSError:
        break
    if pid == 0:
        time.sleep(60)
        os._exit(0)
    kids.append(pid)
for pid in kids:
    os.kill(pid, signal.SIGKILL)
    os.waitpid(pid, 0)
print(len(kids))
"""


@pytest.mark.integration
@pytest.mark.parametrize("sandbox", SANDBOXES)
def test_max_procs_gives_a_warm_run_the_processes_of_a_cold_one(sandbox, toy, run_tmp,
                                                                 tmp_path):
    # a warm run's manager waits in the run's cgroup (a standby) from the second run on:
    # it must not take one of the script's processes
    if pids_cgroup_parent() is None:
        pytest.skip("no writable pids cgroup here")
    script = tmp_path / "forks.py"
    script.write_text(_COUNT_FORKS)
    images = sorted((toy / "images").iterdir())[:3]
    counts = {}
    for warm in (False, True):
        settings = RunSettings(limits=RunLimits(timeout_s=30.0, max_procs=6), sandbox=sandbox,
                               warm=warm)
        pipe = CommandPipeline(f"{PY} {script} --image {{image}}", settings=settings)
        counts[warm] = [int(pipe.run(image).stdout.split()[-1]) for image in images]
        assert (pipe.command.warm is not None) == warm
        pipe.close()
    assert counts[False] == counts[True] == [5, 5, 5]  # the script and five more


def _standby_cgroups(server):
    """The run cgroups that hold one process of ``server``'s tree each: its standbys."""
    from arenabench.eval.runs.proctools import descendants

    parent = Path(server.cgroup if server.isolate else pids_cgroup_parent())
    tree = set(descendants(server.proc.pid))
    found = []
    for group in parent.glob("arenabench-run-*"):
        try:
            procs = [int(p) for p in (group / "cgroup.procs").read_text().split()]
        except OSError:
            continue
        if len(procs) == 1 and procs[0] in tree:
            found.append(group)
    return found


@pytest.mark.integration
@pytest.mark.parametrize("sandbox", SANDBOXES)
def test_standby_managers_wait_in_run_cgroups_that_go_with_the_server(sandbox, toy, runs):
    from concurrent.futures import ThreadPoolExecutor

    from hostile_util import wait_for

    from arenabench.eval.runs.warm_server import STANDBYS

    if pids_cgroup_parent() is None:
        pytest.skip("no writable pids cgroup here")
    images = sorted((toy / "images").iterdir())
    pipe = _probe(sandbox, env={"PROBE_BAD": _sha(images[3]), "PROBE_MODE": "slow"},
                  context=runs)
    seen = set()
    for image in images[:3]:
        assert pipe.run(image).status == "ok"
        (server,) = runs.servers.servers()
        standbys = wait_for(lambda s=server: len(_standby_cgroups(s)) == STANDBYS and
                            _standby_cgroups(s), timeout=10)
        assert standbys, _standby_cgroups(server)
        seen |= set(standbys)
    assert len(seen) == STANDBYS + 2  # one used by each run after the first
    # standbys that die while they wait, during a run (3 s): the server reaps them, reports
    # the run's end as it comes, and forks the next run's manager
    before = set(_standby_cgroups(server))
    with ThreadPoolExecutor(1) as pool:
        slow = pool.submit(pipe.run, images[3])
        # the run has taken a standby and the server has forked the one that replaces it
        waiting = wait_for(lambda s=server: len(now := _standby_cgroups(s)) == STANDBYS and
                           set(now) != before and now)
        assert waiting and not slow.done()
        for group in waiting:
            os.kill(int((group / "cgroup.procs").read_text()), 9)
        pred = slow.result(timeout=15)
    assert pred.status == "ok" and pred.latency_ms < 10_000, (pred.message, pred.latency_ms)
    pred = pipe.run(images[0])
    assert pred.status == "ok" and _seen(pred)["preloaded"] == ["cv2", "numpy"], pred.message
    assert not server.dead
    seen |= set(waiting) | set(_standby_cgroups(server))
    runs.close()
    assert not [g for g in seen if g.exists()], "a standby's cgroup was left behind"


@pytest.mark.parametrize("module, argv", [
    ("arenabench.eval.commands.eval", ["data", "--cmd", "x {image}"]),
    ("arenabench.eval.commands.sweep", ["--preset", "eyrc", "--cmd", "x {image}", "--out", "o"]),
    ("arenabench.eval.commands.grade", ["subs", "data", "--cmd", "x {image}", "--out", "o"]),
])
def test_no_warm_is_an_option_of_eval_sweep_and_grade(module, argv):
    import importlib

    from arenabench.eval.runs.limits import run_settings_from_args

    parser = importlib.import_module(module).build_parser()
    assert run_settings_from_args(parser.parse_args([*argv, "--no-warm"])).warm is False
    assert run_settings_from_args(parser.parse_args(argv)).warm is True


@pytest.mark.integration
@pytest.mark.parametrize("sandbox", SANDBOXES)
def test_a_server_outlives_the_thread_that_started_it(sandbox, toy, runs):
    # PR_SET_PDEATHSIG follows the thread that started the keeper: the end of that thread
    # (a pool's worker, a caller's own thread) is not the end of the harness
    import threading

    images = sorted((toy / "images").iterdir())
    pipe = _probe(sandbox, context=runs)
    first = []
    starter = threading.Thread(target=lambda: first.append(pipe.run(images[0])))
    starter.start()
    starter.join()
    assert first[0].status == "ok", (first[0].message, first[0].stderr)
    (server,) = runs.servers.servers()
    # the thread has left the kernel too: a death signal tied to it has been sent by now
    from hostile_util import wait_for

    assert wait_for(lambda: not Path(f"/proc/self/task/{starter.native_id}").exists())
    assert server.proc.poll() is None, server.proc.returncode
    again = pipe.run(images[1])
    assert again.status == "ok", (again.message, again.stderr)
    assert runs.servers.servers() == [server] and not server.dead


@pytest.mark.integration
@pytest.mark.parametrize("sandbox", SANDBOXES)
def test_sigkill_of_the_harness_ends_the_server_and_its_runs(sandbox, toy, tmp_path):
    import subprocess

    from hostile_util import processes_with, wait_for

    marker = f"warm-sigkill-{os.getpid()}-{sandbox}"
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    argv = [PY, "-m", "arenabench", "eval", str(toy), "--cmd",
            f"{PY} {PIPES / 'hostile' / 'hang_on.py'} --image {{image}}", "--env", "HANG=all",
            "--env", f"MARKER={marker}", "--workers", "2", "--no-progress", "--formats", "json",
            "--out", str(tmp_path / "out"), "--sandbox", sandbox]
    proc = subprocess.Popen(argv, env={**os.environ, "TMPDIR": str(tmpdir)},
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        assert wait_for(lambda: len(processes_with(f"{marker}:child")) >= 4, timeout=60)
        servers = [p for p in processes_with("arenabench-warm-") if p in
                   processes_with(str(tmpdir))]
        assert servers, "no warm server ran the command"
        proc.kill()
        proc.wait()
    finally:
        proc.kill()
    assert wait_for(lambda: not processes_with(f"{marker}:child"), timeout=10)
    assert wait_for(lambda: not processes_with(str(tmpdir)), timeout=10)  # keeper, server
    assert wait_for(lambda: not list(tmpdir.iterdir()), timeout=10), list(tmpdir.iterdir())


@dataclass(frozen=True)
class _KeepAnswer(Command):
    """A command whose ``obstacles.txt`` bytes are kept (read where the harness reads it)."""

    answers: dict = field(default_factory=dict, compare=False, hash=False)

    def interpret(self, result, stdout, stderr, workdir):
        path = Path(workdir, "obstacles.txt")
        self.answers[_sha(next(Path(workdir).glob("image.*")))] = (
            path.read_bytes() if path.exists() else None, result.rc, stdout, stderr)
        return super().interpret(result, stdout, stderr, workdir)


def _keeping_answers(pipe: CommandPipeline) -> _KeepAnswer:
    """``pipe`` made to keep its answers' bytes (its command swapped for a keeping one)."""
    c = pipe.command
    pipe.command = _KeepAnswer(**{f.name: getattr(c, f.name) for f in fields(Command)})
    return pipe.command


@pytest.fixture(scope="module")
def twin50(shared_sets):
    data = shared_sets.generated("eyrc", count=50, seed=11, workers=2)
    return sorted((data / "images").iterdir())


@pytest.mark.acceptance  # the seven styles on 50 scenes, warm and cold: minutes
@pytest.mark.parametrize("sandbox", SANDBOXES)
def test_competition_styles_answer_byte_for_byte_the_same_warm_and_cold(sandbox, twin50,
                                                                         run_tmp):
    from concurrent.futures import ThreadPoolExecutor

    from pass_rates import STYLES

    for style in STYLES:
        answers = {}
        for warm in (False, True):
            pipe = CommandPipeline(f"{PY} {PIPES / style}.py --image {{image}}",
                                   settings=RunSettings(sandbox=sandbox, warm=warm))
            keeping = _keeping_answers(pipe)
            with ThreadPoolExecutor(2) as pool:
                preds = list(pool.map(pipe.run, twin50))
            assert all(p.status in ("ok", "markers_not_found") for p in preds), style
            assert (pipe.command.warm is not None) == warm
            assert pipe.context.servers.servers() if warm else True
            answers[warm] = keeping.answers
            pipe.close()
        assert len(answers[True]) == len(twin50), style
        assert answers[True] == answers[False], style
        assert all(a[0] is not None for a in answers[True].values()), style
