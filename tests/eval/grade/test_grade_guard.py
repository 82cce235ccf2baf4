"""Organiser grading that cannot go silently wrong or be gamed, end to end with
real subprocesses and real bubblewrap: unguessable sets, the preflight, any interpreter in
the sandbox, fail closed, hidden GT wherever the images live, symlinked teams, systemic
failures, null latency, the INCOMPLETE banner and what /proc shows inside the sandbox."""

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from clirun import CliResult, env_changes, run_cli
from paths import TESTS
from procs_limit import GRADE_ARGS, PY_CMD, grade_settings

from arenabench.eval.grade.grading import STATE_FILE, GradeOptions, grade
from arenabench.eval.runs import warm_client
from arenabench.eval.runs.sandbox import bwrap_problem
from arenabench.exitcodes import ExitCode
from arenabench.seeds import GUESSABLE_BELOW

HERE = TESTS
ATTACKS = HERE / "grade_attacks"
needs_bwrap = pytest.mark.skipif(bwrap_problem() is not None, reason=str(bwrap_problem()))
ANSWER = """\
from pathlib import Path
Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\\nObstacles: {count}\\nArea: 1.0\\n")
"""


def _env(**extra: str) -> dict[str, str]:
    """This environment with this Python's bin folder first, so 'python3' has arenabench."""
    path = f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"
    return {**os.environ, "PATH": path, **extra}


def _cli(*args: str, env: dict[str, str] | None = None) -> CliResult:
    """``arenabench ARGS`` in this process with the environment ``env`` (default :func:`_env`)."""
    return run_cli(*args, env=env_changes(env or _env()))


def _grade(*args: str, env: dict[str, str] | None = None) -> CliResult:
    return _cli("grade", *args, *GRADE_ARGS, "--no-progress", "--formats", "json,md,html",
                env=env)


def _grade_process(*args: str, env: dict[str, str]) -> subprocess.CompletedProcess:
    """``arenabench grade ARGS`` in a fresh interpreter: whether bubblewrap works is probed
    once per process, so a PATH without it needs a process of its own."""
    return subprocess.run([sys.executable, "-m", "arenabench", "grade", *args, *GRADE_ARGS,
                           "--no-progress", "--formats", "json,md,html"],
                          capture_output=True, text=True, env=env, timeout=600)


def _team(root: Path, name: str, text: str) -> Path:
    (root / name).mkdir(parents=True, exist_ok=True)
    (root / name / "map.py").write_text(text)
    return root / name


def _one_line_error(proc: CliResult | subprocess.CompletedProcess, needle: str,
                    code: int = 2) -> str:
    err = proc.stderr.strip()
    assert proc.returncode == code, (proc.returncode, err[-3000:])
    assert len(err.splitlines()) == 1 and needle in err and "Traceback" not in err, err
    return err


@pytest.fixture(scope="module")
def random_set(tmp_path_factory):
    out = tmp_path_factory.mktemp("guard-random") / "hidden"
    proc = _cli("generate", "--count", "1", "--seed", "random", "--out", str(out),
                "--workers", "1", "--no-progress")
    assert proc.returncode == 0, proc.stderr[-2000:]
    return out, proc.stdout


@pytest.fixture(scope="module")
def seed3_set(shared_sets):
    return shared_sets.generated("eyrc", count=1, seed=3)


# ----------------------------------------------------------------------------- seeds


def test_generate_seed_random_prints_and_records_a_128_bit_seed(random_set):
    out, stdout = random_set
    seed = json.loads((out / "dataset.json").read_text())["args"]["seed"]
    assert GUESSABLE_BELOW <= seed < 2**128
    assert f"seed {seed} (random" in stdout


def test_grade_refuses_a_guessable_seed_before_any_team(seed3_set, tmp_path):
    subs = tmp_path / "subs"
    _team(subs, "a", ANSWER.format(count=1))
    out = tmp_path / "out"
    proc = _grade(str(seed3_set), str(subs), "--out", str(out), "--cmd", PY_CMD)
    err = _one_line_error(proc, "seed 3")
    assert "--seed random" in err and "--allow-guessable-seed" in err
    assert not out.exists()


def _with_seeds(src: Path, dst: Path, *, meta: object = "keep", gt: object = "keep",
                gt_index: int | None = None) -> Path:
    """A copy of the generated set ``src`` whose ``dataset.json`` records the seed ``meta``
    (top level and ``args``), and whose GT files (or only the one at ``gt_index``) record
    ``gt`` (``"absent"``: none); ``meta`` may also be ``"missing"``, ``"directory"`` or
    ``"garbage"``. The manifest's hashes follow."""
    import hashlib

    shutil.copytree(src, dst)
    meta_path = dst / "dataset.json"
    if meta == "missing":
        meta_path.unlink()
    elif meta == "directory":
        meta_path.unlink()
        meta_path.mkdir()
    elif meta == "garbage":
        meta_path.write_text("{not json")
    elif meta != "keep":
        doc = json.loads(meta_path.read_text())
        doc["seed"] = doc["args"]["seed"] = meta
        meta_path.write_text(json.dumps(doc))
    rows = [json.loads(line) for line in (dst / "manifest.jsonl").read_text().splitlines()]
    for i, row in enumerate(rows):
        if gt != "keep" and gt_index in (None, i):
            path = dst / row["gt"]
            doc = json.loads(path.read_text())
            if gt == "absent":
                del doc["seed"]
            else:
                doc["seed"] = gt
            path.write_text(json.dumps(doc))
            row["gt_sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
    (dst / "manifest.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return dst


BIG_SEED = GUESSABLE_BELOW + 12345


@pytest.mark.parametrize(
    ("meta", "gt", "needle"),
    [
        ("3", "keep", "dataset.json: seed '3' is not an integer"),
        (3.0, "keep", "dataset.json: seed 3.0 is not an integer"),
        (-1, "keep", "dataset.json: seed -1 is below 2**64"),
        (None, "keep", "dataset.json: no seed recorded"),
        ([1], "keep", "dataset.json: seed [1] is not an integer"),
        (True, "keep", "dataset.json: seed True is not an integer"),
        (2**64 - 1, "keep", f"dataset.json: seed {2**64 - 1} is below 2**64"),
        ("missing", BIG_SEED, "dataset.json: missing"),
        ("garbage", BIG_SEED, "dataset.json: not JSON"),
        ("missing", 1, "dataset.json: missing"),
        (BIG_SEED, 1, "gt/000000.json: seed 1 is below 2**64"),
        (BIG_SEED, "absent", "gt/000000.json: no seed recorded"),
        (BIG_SEED, float(BIG_SEED), "gt/000000.json: seed 1.8446744073709564e+19 is not an "
                                    "integer"),
    ],
    ids=["str", "float", "negative", "null", "list", "true", "2**64-1", "no-dataset.json",
         "dataset.json-garbage", "no-dataset.json-gt-1", "big-dataset.json-gt-1",
         "gt-without-seed", "gt-float"],
)
def test_grade_refuses_a_seed_not_proven_unguessable_wherever_it_is_recorded(
        seed3_set, tmp_path, meta, gt, needle):
    err = _refused_seeded_grade(seed3_set, tmp_path, meta, gt, needle)
    assert "--seed random" in err and "--allow-guessable-seed" in err, err


def _refused_seeded_grade(seed3_set: Path, tmp_path: Path, meta: object, gt: object,
                          needle: str, *args: str) -> str:
    """The one-line refusal of a grade of ``_with_seeds(seed3_set, ...)``, holding
    ``DATA/needle``; nothing is written."""
    data = _with_seeds(seed3_set, tmp_path / "hidden", meta=meta, gt=gt)
    subs = tmp_path / "subs"
    _team(subs, "a", ANSWER.format(count=1))
    out = tmp_path / "out"
    err = _one_line_error(_grade(str(data), str(subs), "--out", str(out), "--cmd", PY_CMD,
                                 *args), f"{data}/{needle}")
    assert not out.exists()
    return err


@pytest.mark.parametrize(
    ("meta", "gt", "needle"),
    [
        ("directory", BIG_SEED, "dataset.json: not a regular file (a directory)"),
        (BIG_SEED, "3", "gt/000000.json: seed: '3' is not of type 'integer'"),
        (BIG_SEED, None, "gt/000000.json: seed: None is not of type 'integer'"),
    ],
    ids=["dataset.json-folder", "gt-str", "gt-null"],
)
def test_a_seed_no_generator_writes_is_a_dataset_error_even_when_guessable_is_allowed(
        seed3_set, tmp_path, meta, gt, needle):
    _refused_seeded_grade(seed3_set, tmp_path, meta, gt, needle, "--allow-guessable-seed")


def test_a_set_whose_every_seed_is_big_passes_the_seed_check(seed3_set, tmp_path):
    from arenabench.eval.datasets.reader import load_dataset
    from arenabench.eval.grade.preflight import PreflightError, check_dataset_seed

    data = _with_seeds(seed3_set, tmp_path / "hidden", meta=BIG_SEED, gt=BIG_SEED)
    assert check_dataset_seed(load_dataset(data), allow_guessable=False) == BIG_SEED
    # and the flag lets a guessable one through
    weak = _with_seeds(seed3_set, tmp_path / "weak", meta=BIG_SEED, gt=1)
    with pytest.raises(PreflightError, match="seed 1 is below"):
        check_dataset_seed(load_dataset(weak), allow_guessable=False)
    check_dataset_seed(load_dataset(weak), allow_guessable=True)


@pytest.mark.integration
def test_answers_beyond_any_scene_are_bad_output_and_every_team_is_ranked(seed3_set, tmp_path):
    """2**53 once stopped a team's report ("array is too big") and 6000 took minutes and
    gigabytes (the count confusion grew with the count squared): both are bad_output now, and
    every report of every team is written."""
    subs = tmp_path / "subs"
    _team(subs, "huge", ANSWER.format(count=2**53))
    _team(subs, "many", ANSWER.format(count=6000))
    _team(subs, "plain", ANSWER.format(count=1))
    formats = ("json", "csv", "md", "html", "junit")
    result = grade(seed3_set, subs, tmp_path / "out", options=GradeOptions(
        command=PY_CMD, formats=formats, settings=grade_settings(sandbox="none")),
        workers=2, report_workers=1, allow_guessable_seed=True)
    assert result.errors == {}
    rows = {r.team: r for r in result.rows}
    assert set(rows) == {"huge", "many", "plain"}
    for team in ("huge", "many"):
        failures = {k: v for k, v in rows[team].summary.failures.items() if v}
        assert failures == {"bad_output": 1}, rows[team].summary
        report = json.loads((tmp_path / "out" / "teams" / team / "report.json").read_text())
        assert "obstacle count is larger than 1000" in report["images"][0]["message"]
        for name in ("report.html", "report.md", "junit.xml", "results.csv"):
            assert (tmp_path / "out" / "teams" / team / name).is_file(), (team, name)
    doc = json.loads((tmp_path / "out" / "leaderboard.json").read_text())
    assert {t["team"] for t in doc["teams"]} == {"huge", "many", "plain"}


@pytest.mark.integration
@needs_bwrap
def test_seed_brute_force_wins_on_seed_3_and_fails_on_a_random_set(random_set, seed3_set,
                                                                   tmp_path):
    # the worst case: the grading interpreter is the project's own, so the submission can
    # import the generator; the preflight says so on stderr
    subs = tmp_path / "subs"
    shutil.copytree(ATTACKS / "seed_brute_force", subs / "brute")
    guessable = _grade(str(seed3_set), str(subs), "--out", str(tmp_path / "o3"), "--cmd",
                       PY_CMD, "--allow-guessable-seed", "--timeout", "120")
    assert guessable.returncode == 0, guessable.stderr[-3000:]
    assert "arenabench is importable inside the sandbox" in guessable.stderr
    team = json.loads((tmp_path / "o3" / "leaderboard.json").read_text())["teams"][0]
    assert team["n_passed"] == 1  # the attack is real: it found seed 3 and copied the GT

    proc = _grade(str(random_set[0]), str(subs), "--out", str(tmp_path / "or"), "--cmd",
                  PY_CMD, "--timeout", "120")
    assert proc.returncode == 0, proc.stderr[-3000:]
    team = json.loads((tmp_path / "or" / "leaderboard.json").read_text())["teams"][0]
    assert team["n_passed"] == 0 and team["failures"]["wrong_count"] == 1
    rep = json.loads((tmp_path / "or" / "teams" / "brute" / "report.json").read_text())
    assert "seed not found" in rep["images"][0]["stderr_tail"]


# ----------------------------------------------------------------------------- sandbox view

SNOOP = """\
import base64, glob, json, os, sys, zlib
from pathlib import Path
seen = {"cmdline": {}, "gt": []}
for d in glob.glob("/proc/[0-9]*"):
    try:
        args = Path(d, "cmdline").read_bytes().decode().split("\\0")
        seen["cmdline"][d] = [a[:100] for a in args[:4]]  # (the report keeps 2,000 characters)
    except OSError:
        pass
seen["mountinfo"] = [" ".join(line.split()[3:5])
                     for line in Path("/proc/self/mountinfo").read_text().splitlines()]
seen["environ"] = Path("/proc/self/environ").read_bytes().decode()
for arg in sys.argv[1:]:
    if arg.startswith("/") and not arg.startswith("/sandbox") and os.path.exists(arg):
        top = Path(arg).parent
        seen["gt"] += [str(p) for pattern in ("*.json", "*.png", "*.jpg")
                       for p in top.rglob(pattern)]
print(base64.b64encode(zlib.compress(json.dumps(seen).encode(), 9)).decode(), file=sys.stderr)
Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\\nObstacles: 0\\nArea: 0\\n")
"""


@pytest.mark.integration
@needs_bwrap
@pytest.mark.parametrize("warm", [False, True], ids=["cold", "warm"])
def test_pics_folder_keeps_gt_hidden_and_proc_names_no_host_paths(seed3_set, tmp_path, warm):
    # the dataset sits inside a folder the command makes visible (a shared config folder),
    # its images in pics/ (not images/)
    shared = tmp_path / "shared"
    data = shared / "set"
    shutil.copytree(seed3_set, data)
    (data / "images").rename(data / "pics")
    data_suffix = next((data / "pics").iterdir()).suffix  # .jpg for eyrc
    lines = (data / "manifest.jsonl").read_text().replace('"images/', '"pics/')
    (data / "manifest.jsonl").write_text(lines)
    (shared / "config.txt").write_text("x")
    subs = tmp_path / "subs"
    _team(subs, "snoop", SNOOP)
    out = tmp_path / "out"
    cmd = f"{PY_CMD} {shared / 'config.txt'}"
    opts = GradeOptions(command=cmd, formats=("json",), settings=grade_settings(warm=warm))
    grade(data, subs, out, options=opts, workers=1, allow_guessable_seed=True)
    rep = json.loads((out / "teams" / "snoop" / "report.json").read_text())
    import base64
    import zlib

    packed = rep["images"][0]["stderr_tail"].strip().splitlines()[-1]
    seen = json.loads(zlib.decompress(base64.b64decode(packed)))
    assert seen["gt"] == []  # nothing of the dataset: no GT, no images
    for host in (str(data), str(out), "arenabench-run-"):
        assert host not in json.dumps(seen["cmdline"]) and host not in seen["environ"], host
    # mountinfo lists the mount points: the system folders, the interpreter's, the
    # submission's, the visible shared folder and, hidden under empty tmpfs, the dataset's
    from arenabench.eval.runs.interpreter import interpreter_folders

    allowed = {str(subs / "snoop"), str(shared), str(data), str(data / "pics"),
               *interpreter_folders(sys.executable).folders}
    points = {line.split()[1] for line in seen["mountinfo"]}
    system = ("/usr", "/sandbox", "/proc", "/dev", "/etc", "/bin", "/sbin", "/lib", "/lib64")
    if warm:  # the warm server's own mount points inside the sandbox: no host path in them
        system += ("/.arenabench-warm", "/.arenabench-cgroup", warm_client.THP_SETTINGS)
    host = {p for p in points if p not in ("/", "/tmp")
            and not any(p == s or p.startswith(s + "/") for s in system)}
    assert host <= allowed and str(subs / "snoop") in host
    assert "bwrap" not in json.dumps(seen["cmdline"])  # no bubblewrap argv (bind list)
    pid1 = seen["cmdline"]["/proc/1"]
    assert pid1[0] == sys.executable
    if warm:  # pid 1 is the warm server (python -c SOURCE: public code), the runs its children
        assert pid1[1] == "-c" and "warm interpreter" in pid1[2]
    else:
        assert pid1[1] == str(subs / "snoop" / "map.py")
        assert pid1[2] == "--image" and pid1[3] == "/sandbox/image" + data_suffix
    assert sys.executable.split("/bin/")[0] in seen["environ"]  # PATH: the interpreter's bin
    assert os.environ["PATH"] not in seen["environ"]


@pytest.mark.integration
@needs_bwrap
def test_symlinked_team_grades_like_its_target(seed3_set, tmp_path):
    elsewhere = _team(tmp_path / "real", "team_src", ANSWER.format(count=1))
    subs = tmp_path / "subs"
    subs.mkdir()
    (subs / "linked").symlink_to(elsewhere)
    shutil.copytree(elsewhere, subs / "copied")
    result = grade(seed3_set, subs, tmp_path / "out", options=GradeOptions(
        command=PY_CMD, formats=("json",), settings=grade_settings()), workers=2,
        allow_guessable_seed=True)
    rows = {r.team: r for r in result.rows}
    assert rows["linked"].summary.to_dict() | {"latency_ms": None} == \
        rows["copied"].summary.to_dict() | {"latency_ms": None}
    assert rows["linked"].summary.failures.get("crash", 0) == 0
    assert rows["linked"].submission_sha256 == rows["copied"].submission_sha256


# ----------------------------------------------------------------------------- interpreters


@pytest.fixture(scope="session")
def teams_venv(competition_cache):
    """A second, real virtual environment with its own numpy and OpenCV at the competition's
    versions: the competition's environment, made once per session from the package index."""
    from arenabench.eval.runs.competition_env import env_folder

    return env_folder(competition_cache)


@pytest.mark.integration
@needs_bwrap
@pytest.mark.parametrize("named", ["by its path", "{competition_python}"])
def test_a_second_venv_grades_a_correct_team_100(seed3_set, teams_venv, competition_cache,
                                                 tmp_path, named):
    subs = tmp_path / "subs"
    shutil.copytree(HERE / "grade_teams" / "correct", subs / "correct")
    # the team's script is the reference detector with its source alongside (the teams'
    # venv has no arenabench), as the built-in preflight reference is laid out
    from arenabench.eval.grade.preflight import builtin_reference

    shutil.rmtree(subs / "correct")
    (subs / "correct").mkdir()
    builtin_reference(subs / "correct", "python {submission}/map.py", output="obstacles")
    out = tmp_path / "out"
    python = teams_venv / "bin" / "python"
    shown = python if named == "by its path" else named
    proc = _grade(str(seed3_set), str(subs), "--out", str(out), "--allow-guessable-seed",
                  "--cmd", f"{shown} {{submission}}/map.py --image {{image}}",
                  env=_env(ARENABENCH_CACHE_DIR=str(competition_cache)))
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert doc_executable(out) == str(python)
    assert "importable" not in proc.stderr  # the teams' venv has no arenabench
    doc = json.loads((out / "leaderboard.json").read_text())
    assert doc["teams"][0]["pass_rate"] == 1.0
    box = doc["sandbox"]
    assert box["mode"] == "bwrap" and box["kind"] == "venv"
    from arenabench.eval.runs.competition_env import COMPETITION_PINS

    for pin in COMPETITION_PINS:
        assert pin.matches(box["versions"][pin.module])
    assert box["arenabench_importable"] is False
    rep = json.loads((out / "teams" / "correct" / "report.json").read_text())
    assert rep["sandbox"]["versions"] == box["versions"]


def doc_executable(out: Path) -> str:
    """The interpreter the preflight saw (``leaderboard.json``)."""
    return json.loads((out / "leaderboard.json").read_text())["sandbox"]["executable"]


def _no_team_graded(out: Path) -> bool:
    return not out.exists() or not list(out.rglob(STATE_FILE))


def test_python_without_cv2_stops_at_the_preflight(seed3_set, tmp_path):
    bare = tmp_path / "bare-venv"
    base = Path(sys.base_prefix) / "bin" / "python3"
    subprocess.run([str(base), "-m", "venv", "--without-pip", str(bare)], check=True,
                   timeout=120)
    subs = tmp_path / "subs"
    _team(subs, "a", ANSWER.format(count=1))
    out = tmp_path / "out"
    proc = _grade(str(seed3_set), str(subs), "--out", str(out), "--allow-guessable-seed",
                  "--cmd", f"{bare}/bin/python {{submission}}/map.py --image {{image}}")
    err = _one_line_error(proc, "preflight")
    assert "cv2" in err and str(bare) in err
    assert _no_team_graded(out)


def test_a_broken_interpreter_stops_at_the_preflight(seed3_set, tmp_path):
    broken = tmp_path / "broken" / "bin" / "python3"
    broken.parent.mkdir(parents=True)
    broken.write_text("#!/bin/sh\necho 'Fatal Python error: init_fs_encoding: failed to get "
                      "the Python codec of the filesystem encoding' >&2\nexit 1\n")
    broken.chmod(0o755)
    subs = tmp_path / "subs"
    _team(subs, "a", ANSWER.format(count=1))
    out = tmp_path / "out"
    proc = _grade(str(seed3_set), str(subs), "--out", str(out), "--allow-guessable-seed",
                  "--cmd", f"{broken} {{submission}}/map.py --image {{image}}")
    err = _one_line_error(proc, "preflight")
    assert "Fatal Python error" in err
    assert _no_team_graded(out)


def test_a_relative_interpreter_is_named_as_relative_to_each_team_folder(seed3_set, tmp_path):
    """Relative paths in --cmd resolve from each team's folder: the preflight says so, and
    never names its own temporary folder."""
    subs = tmp_path / "subs"
    _team(subs, "a", ANSWER.format(count=1))
    out = tmp_path / "out"
    proc = _grade(str(seed3_set), str(subs), "--out", str(out), "--allow-guessable-seed",
                  "--cmd", "venv/bin/python {submission}/map.py --image {image}")
    err = _one_line_error(proc, "venv/bin/python")
    assert "relative paths resolve from each team's folder" in err
    assert "arenabench-preflight" not in err
    assert _no_team_graded(out)


@pytest.mark.integration
def test_sandbox_none_is_required_without_bubblewrap(seed3_set, tmp_path):
    # a PATH without bubblewrap (the harness is started by its absolute path)
    nobwrap = tmp_path / "bin"
    nobwrap.mkdir()
    for tool in ("true", "sh"):
        os.symlink(shutil.which(tool), nobwrap / tool)
    env = {**os.environ, "PATH": str(nobwrap)}
    subs = tmp_path / "subs"
    _team(subs, "a", ANSWER.format(count=1))
    out = tmp_path / "out"
    base = ["--out", str(out), "--allow-guessable-seed", "--cmd", PY_CMD]
    proc = _grade_process(str(seed3_set), str(subs), *base, env=env)
    err = _one_line_error(proc, "bubblewrap")
    assert "apt-get install bubblewrap" in err and "--sandbox none" in err
    assert not out.exists()
    proc = _grade_process(str(seed3_set), str(subs), *base, "--sandbox", "none", env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert json.loads((out / "leaderboard.json").read_text())["sandbox"]["mode"] == "none"


# ----------------------------------------------------------------------------- leaderboard


@pytest.mark.integration
def test_six_teams_failing_alike_exit_non_zero(seed3_set, tmp_path):
    subs = tmp_path / "subs"
    for i in range(6):
        _team(subs, f"t{i}", "import no_such_module_for_grading\n")
    out = tmp_path / "out"
    proc = _grade(str(seed3_set), str(subs), "--out", str(out), "--allow-guessable-seed",
                  "--cmd", PY_CMD)
    err = [line for line in proc.stderr.strip().splitlines() if "WARNING" not in line]
    assert proc.returncode == ExitCode.SYSTEMIC, proc.stderr[-3000:]
    assert len(err) == 1 and "6 of 6 teams fail alike" in err[0]
    assert "no_such_module_for_grading" in err[0] and "Traceback" not in proc.stderr
    assert (out / "leaderboard.json").is_file()


@pytest.mark.integration
def test_an_all_timeout_team_ranks_last_with_null_latency(seed3_set, tmp_path):
    subs = tmp_path / "subs"
    _team(subs, "a_sleeps", "import time\ntime.sleep(60)\n")
    _team(subs, "b_wrong", ANSWER.format(count=99))
    opts = GradeOptions(command=PY_CMD, formats=("json",),
                        settings=_settings(timeout_s=2.0))
    result = grade(seed3_set, subs, tmp_path / "out", options=opts, workers=2,
                   allow_guessable_seed=True)
    doc = json.loads(result.files["leaderboard.json"].read_text())
    assert [t["team"] for t in doc["teams"]] == ["b_wrong", "a_sleeps"]
    last = doc["teams"][-1]
    assert last["failures"]["timeout"] == 1 and last["latency_ms_median"] is None
    assert last["rank"] == 2 and not last["tied"]
    assert "latency" not in json.dumps(doc["ranking"])


@pytest.mark.integration
def test_byte_identical_submissions_share_one_rank_every_run(seed3_set, tmp_path):
    subs = tmp_path / "subs"
    for name in ("x", "y", "z"):
        _team(subs, name, ANSWER.format(count=1))
    _team(subs, "w", ANSWER.format(count=99))
    ranks = []
    for run in range(2):
        result = grade(seed3_set, subs, tmp_path / f"out{run}", options=GradeOptions(
            command=PY_CMD, formats=("json",), settings=grade_settings()), workers=3,
            allow_guessable_seed=True)
        ranks.append([(r.team, r.rank, r.tied) for r in result.rows])
        csv_text = result.files["leaderboard.csv"].read_text()
        assert [line.split(",")[0] for line in csv_text.splitlines()[1:4]] == ["1", "1", "1"]
    assert ranks[0] == ranks[1]
    top = [r for r in ranks[0] if r[0] in "xyz"]
    assert {(rank, tied) for _, rank, tied in top} == {(1, True)}
    assert [t for t, _, _ in top] == ["x", "y", "z"]  # listed by name


def _settings(**limits):
    return grade_settings(limits=limits)


# ----------------------------------------------------------------------------- INCOMPLETE


def _dom(page: Path, tmp_path: Path) -> str:
    from browser import CHROMIUM_FLAGS, find_chromium

    chromium = find_chromium()
    if chromium is None:
        pytest.skip("chromium is not installed (apt-get install -y chromium)")
    proc = subprocess.run([chromium, *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'prof'}",
                           "--dump-dom", page.resolve().as_uri()],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc.stdout


@pytest.mark.integration
def test_interrupted_grade_and_eval_show_the_banner(shared_sets, tmp_path):
    data = shared_sets.generated("eyrc", count=3, seed=3)
    # eval: the second image hangs (after leaving a mark); SIGINT once it does
    slow, mark = tmp_path / "slow.py", tmp_path / "sleeping"
    slow.write_text("import sys, time\nfrom pathlib import Path\n"
                    "if Path(sys.argv[1]).stat().st_size != Path(sys.argv[2]).stat().st_size:\n"
                    f"    Path({str(mark)!r}).touch()\n    time.sleep(300)\n"
                    + ANSWER.format(count=1))
    first = sorted((data / "images").iterdir())[0]
    ev = tmp_path / "ev"
    proc = subprocess.Popen(
        [sys.executable, "-m", "arenabench", "eval", str(data), "--cmd",
         f"{sys.executable} {slow} {{image}} {first}", "--workers", "1", "--out", str(ev),
         "--formats", "json,md,html", "--no-progress", "--timeout", "300", "--sandbox", "none"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env())
    try:
        from hostile_util import wait_for

        assert wait_for(mark.exists, timeout=120), "the second image never started"
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 130
    md = (ev / "report.md").read_text()
    report = json.loads((ev / "report.json").read_text())
    done = report["n_done"]
    assert report["n_total"] == 3 and done < 3
    assert f"INCOMPLETE: {done} of 3 images" in md and "Summary (partial)" in md
    dom = _dom(ev / "report.html", tmp_path)
    assert f"INCOMPLETE: {done} of 3 images" in dom and 'id="incomplete"' in dom

    # grade: interrupted after the first of three teams
    subs = tmp_path / "subs"
    for name in ("a", "b", "c"):
        _team(subs, name, ANSWER.format(count=1))
    out = tmp_path / "out"

    def interrupt(line: str) -> None:
        if ": graded" in line:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        grade(data, subs, out, options=GradeOptions(command=PY_CMD, formats=("json",),
                                                    settings=grade_settings()),
              workers=1, report_workers=1, log=interrupt, allow_guessable_seed=True)
    doc = json.loads((out / "leaderboard.json").read_text())
    assert doc["complete"] is False and doc["images_total"] == 9
    banner = f"INCOMPLETE: {doc['images_done']} of 9 images"
    dom = _dom(out / "leaderboard.html", tmp_path)
    assert banner in dom and "Leaderboard (partial)" in dom


def test_sweep_page_of_a_partial_sweep_shows_the_banner(tmp_path):
    from dataclasses import replace

    from arenabench.eval.commands.sweep import main as sweep_main
    from arenabench.eval.sweep.html import sweep_page
    from arenabench.eval.sweep.outputs import load_sweep

    out = tmp_path / "sweep"
    assert sweep_main(["--vary", "camera.tilt_deg=0,10", "--per-point", "1", "--seed", "2",
                       "--pipeline", "seed", "--out", str(out), "--workers", "1",
                       "--no-progress", "--no-plots"]) == 0
    result = load_sweep(out)
    assert "INCOMPLETE" not in sweep_page(result, [])
    partial = replace(result, run={**result.run, "complete": False, "samples_done": 1})
    page = sweep_page(partial, [])
    assert "INCOMPLETE: 1 of 2 images" in page and 'id="incomplete"' in page


@pytest.mark.integration
def test_a_submission_too_large_to_fingerprint_is_refused_alone(seed3_set, tmp_path,
                                                                 monkeypatch):
    from arenabench.eval.grade import submissions

    monkeypatch.setattr(submissions, "MAX_ENTRIES", 50)
    subs = tmp_path / "subs"
    _team(subs, "fine", ANSWER.format(count=1))
    big = _team(subs, "many_files", ANSWER.format(count=1))
    for i in range(60):
        (big / f"f{i}").write_text("")
    result = grade(seed3_set, subs, tmp_path / "out", options=GradeOptions(
        command=PY_CMD, formats=("json",), settings=grade_settings()), workers=1,
        allow_guessable_seed=True)
    assert [r.team for r in result.rows] == ["fine"]
    assert "more than 50 entries" in result.errors["many_files"]


def test_interpreter_folders_of_venv_conda_pyenv_and_scripts(tmp_path):
    from arenabench.eval.runs.interpreter import interpreter_folders

    def exe(path: Path, text: str = "") -> Path:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        path.chmod(0o755)
        return path

    base = exe(tmp_path / "base" / "bin" / "python3")
    venv = tmp_path / "venv"
    (venv / "bin").mkdir(parents=True)
    (venv / "bin" / "python").symlink_to(base)
    (venv / "pyvenv.cfg").write_text(f"home = {base.parent}\n")
    (tmp_path / "extra").mkdir()
    site = venv / "lib" / "python3.11" / "site-packages"
    site.mkdir(parents=True)
    (site / "extra.pth").write_text(f"{tmp_path / 'extra'}\n")
    info = interpreter_folders(venv / "bin" / "python")
    assert info.kind == "venv"
    assert set(info.folders) == {str(venv), str(tmp_path / "base"), str(tmp_path / "extra")}

    conda = exe(tmp_path / "conda" / "envs" / "teams" / "bin" / "python")
    (conda.parent.parent / "conda-meta").mkdir()
    info = interpreter_folders(conda)
    assert info.kind == "conda" and info.folders == (str(conda.parent.parent),)

    shim = exe(tmp_path / "pyenv" / "shims" / "python3", "#!/usr/bin/env bash\n")
    info = interpreter_folders(shim)
    assert info.kind == "pyenv" and info.folders == (str(tmp_path / "pyenv"),)

    script = exe(tmp_path / "tools" / "bin" / "grade-run", f"#!{conda}\nprint(1)\n")
    info = interpreter_folders(script)
    assert info.kind == "conda"
    assert set(info.folders) == {str(tmp_path / "tools"), str(conda.parent.parent)}

    assert interpreter_folders("/usr/bin/python3").folders == ()  # /usr: always visible
