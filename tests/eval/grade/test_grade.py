"""``arenabench grade`` end to end: six real submissions (tests/grade_teams) run as
subprocesses on a small rendered eyrc set are ranked as expected; grading again skips them
all; a Dask ``LocalCluster`` on loopback gives the same leaderboard (latency aside); changed
submissions or options are graded again, an interrupted grade resumes; usage errors exit 2;
the leaderboard page works in a real headless chromium."""

import csv
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from paths import TESTS
from procs_limit import GRADE_ARGS, PY_CMD, grade_settings

from arenabench.cli import main as arenabench_main
from arenabench.eval.grade.grading import STATE_FILE, GradeOptions, grade
from arenabench.eval.grade.leaderboard import (
    LEADERBOARD_JSON_SCHEMA,
    LEADERBOARD_SCHEMA,
    LeaderboardRow,
    rank_rows,
)
from arenabench.eval.grade.submissions import submission_hash
from arenabench.eval.grade.teams import team_command
from arenabench.eval.phase_check import DEFAULT_PHASES
from arenabench.eval.runs import CommandPipeline
from arenabench.eval.scoring.results import Summary

TEAMS_SRC = TESTS / "grade_teams"
TEAMS = ("cheating", "correct", "crashing", "partly_right", "slow", "total_area")
#: 4 images; the timeout only has to stop 'slow' (it sleeps 120 s) and must never stop the
#: others on a loaded machine, where starting Python and OpenCV alone can take a second or two
COUNT, TIMEOUT, WORKERS = 4, "5", "4"


def _env() -> dict[str, str]:
    """This environment with this Python's bin folder first, so 'python3' has arenabench."""
    return {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}


def _grade_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "arenabench", "grade", *args, *GRADE_ARGS,
                           "--no-progress",
                           "--allow-guessable-seed"],
                          capture_output=True, text=True, env=_env(), timeout=600)


def _without_latency(doc):
    """A leaderboard document without wall-clock fields (the only ones allowed to differ): the
    latency, and how many phase-check runs did not complete (a run that times out on a busy
    machine is not a failed run; the labels stay)."""
    doc = json.loads(json.dumps(doc))
    for t in doc["teams"]:
        t.pop("latency_ms_median")
        (t.get("phase_check") or {}).pop("not_completed", None)
    return doc


def _verdicts(images):
    """A report's images without wall-clock fields: latency, output tails, and of the phase
    check all but the label and the runs tried (how many completed and passed depends on
    which runs a busy machine timed out)."""
    strip = ("latency_ms", "stdout_tail", "stderr_tail")
    out = []
    for image in images:
        kept = {k: v for k, v in image.items() if k not in strip}
        if "phase" in kept:
            kept["phase"] = {k: kept["phase"][k] for k in ("class", "runs", "phases")}
        out.append(kept)
    return out


def _distinct_seed() -> int:
    """The first seed whose scenes give every team a different number of passes: with n1
    scenes of 1 obstacle and n_odd of an odd number, 'partly_right' passes COUNT - n1 and
    'crashing' COUNT - n_odd, so the order needs no latency (drawn without rendering)."""
    from arenabench.generator.model.sampler import sample_scene

    for seed in range(1000):
        counts = [sample_scene("eyrc", seed=seed, index=i).params["obstacles.count"]
                  for i in range(COUNT)]
        if 0 < sum(c == 1 for c in counts) < sum(c % 2 for c in counts) < COUNT:
            return seed
    raise AssertionError("no seed gives distinct pass counts")  # pragma: no cover


@pytest.fixture(scope="module")
def dataset(shared_sets):
    return shared_sets.generated("eyrc", count=COUNT, seed=_distinct_seed())


@pytest.fixture(scope="module")
def submissions(tmp_path_factory):
    root = tmp_path_factory.mktemp("grade-subs") / "submissions"
    root.mkdir()
    for team in TEAMS:
        shutil.copytree(TEAMS_SRC / team, root / team)
    return root


@pytest.fixture(scope="module")
def graded(dataset, submissions, tmp_path_factory):
    out = tmp_path_factory.mktemp("grade-out") / "results"
    proc = _grade_cli(str(dataset), str(submissions), "--out", str(out), "--timeout", TIMEOUT,
                      "--workers", WORKERS)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return out, proc


def _gt_counts(dataset):
    return [json.loads(p.read_text())["count"] for p in sorted((dataset / "gt").glob("*.json"))]


@pytest.mark.integration
def test_six_teams_are_ranked_as_expected(graded, dataset):
    jsonschema = pytest.importorskip("jsonschema")
    out, proc = graded
    doc = json.loads((out / "leaderboard.json").read_text())
    jsonschema.validate(doc, LEADERBOARD_JSON_SCHEMA)
    assert doc["schema"] == LEADERBOARD_SCHEMA
    assert doc["dataset"]["n"] == COUNT and len(doc["dataset"]["manifest_sha256"]) == 64
    assert doc["options"]["command"] == "python3 {submission}/map.py --image {image}"
    assert doc["options"]["run"]["timeout_s"] == float(TIMEOUT)
    teams = {t["team"]: t for t in doc["teams"]}
    assert set(teams) == set(TEAMS)
    assert [t["rank"] for t in doc["teams"]] == list(range(1, 7))

    counts = _gt_counts(dataset)
    n_odd = sum(c % 2 for c in counts)
    n_one = sum(c == 1 for c in counts)
    assert COUNT > COUNT - n_one > COUNT - n_odd > 0  # see _distinct_seed
    for team in ("correct", "total_area"):  # 'Total Area:' is read like 'Area:'
        assert teams[team]["n_passed"] == COUNT, teams[team]
    assert teams["partly_right"]["n_passed"] == COUNT - n_one
    assert teams["partly_right"]["failures"]["wrong_count"] == n_one
    # eyrc: failures are phase-checked by default; a wrong count at every phase is robust
    assert teams["partly_right"]["robust_failure_rate"] == n_one / COUNT
    assert teams["partly_right"]["phase_dependent_failure_rate"] == 0.0
    assert teams["correct"]["robust_failure_rate"] is None
    assert teams["crashing"]["n_passed"] == COUNT - n_odd
    assert teams["crashing"]["failures"]["crash"] == n_odd
    assert teams["slow"]["n_passed"] == 0 and teams["slow"]["failures"]["timeout"] == COUNT
    assert teams["slow"]["area_rel_err_median"] is None

    order = [t["team"] for t in doc["teams"] if t["team"] != "cheating"]
    top = sorted(("correct", "total_area"), key=lambda t: teams[t]["area_rel_err_median"])
    assert order == [*top, "partly_right", "crashing", "slow"]

    # every team has eval's report files, linked from the leaderboard
    for name, t in teams.items():
        team_dir = out / "teams" / name
        for f in ("report.json", "results.csv", "report.md", "report.html", "junit.xml",
                  STATE_FILE):
            assert (team_dir / f).is_file(), (name, f)
        assert t["report"] == f"teams/{name}/report.html"
        rep = json.loads((team_dir / "report.json").read_text())
        assert rep["pipeline"] == name and rep["summary"]["n_passed"] == t["n_passed"]
    rows = list(csv.DictReader((out / "leaderboard.csv").read_text().splitlines()))
    assert [r["team"] for r in rows] == [t["team"] for t in doc["teams"]]
    assert rows[-1]["area_rel_err_median"] == "" and rows[-1]["failures_timeout"] == str(COUNT)
    page = (out / "leaderboard.html").read_text()
    assert all(f'href="teams/{name}/report.html"' in page for name in TEAMS)
    assert proc.stdout.count(": graded (") == 6


@pytest.mark.integration
def test_cheating_team_cannot_read_the_ground_truth(graded):
    # Each run sees a private copy of its image under a neutral name (and, with bubblewrap,
    # nothing of the dataset): the cheat finds no GT, answers 0 obstacles on every image and
    # ranks below every team that answered something right.
    out, _ = graded
    doc = json.loads((out / "leaderboard.json").read_text())
    cheat = next(t for t in doc["teams"] if t["team"] == "cheating")
    assert cheat["n_passed"] == 0
    assert cheat["failures"]["wrong_count"] == COUNT
    assert [t["team"] for t in doc["teams"]][-2:] == ["cheating", "slow"]


@pytest.mark.integration
def test_grading_again_skips_every_team(graded, dataset, submissions):
    out, _ = graded
    before = (out / "leaderboard.json").read_bytes()
    stamps = {p: p.stat().st_mtime_ns for p in (out / "teams").rglob("*") if p.is_file()}
    proc = _grade_cli(str(dataset), str(submissions), "--out", str(out), "--timeout", TIMEOUT,
                      "--workers", WORKERS)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.count("skipped: already graded") == 6
    assert "0 graded, 6 skipped" in proc.stdout
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps  # nothing rewritten
    assert (out / "leaderboard.json").read_bytes() == before
    assert not list(submissions.rglob("__pycache__"))  # submissions are only read


@pytest.mark.integration
def test_dask_local_cluster_gives_the_same_leaderboard(graded, dataset, submissions, tmp_path,
                                                       monkeypatch):
    distributed = pytest.importorskip("distributed")
    out, _ = graded
    # the workers run 'python3' from PATH: this Python's
    monkeypatch.setenv("PATH", _env()["PATH"])
    settings = grade_settings(limits={"timeout_s": float(TIMEOUT)})
    with distributed.LocalCluster(n_workers=2, threads_per_worker=2, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        result = grade(dataset, submissions, tmp_path / "dask",  # as the CLI on eyrc
                       options=GradeOptions(settings=settings, phases=DEFAULT_PHASES),
                       scheduler=cluster.scheduler_address, allow_guessable_seed=True)
    assert sorted(result.graded) == sorted(TEAMS) and not result.errors
    local = json.loads((out / "leaderboard.json").read_text())
    remote = json.loads((tmp_path / "dask" / "leaderboard.json").read_text())
    assert _without_latency(remote) == _without_latency(local)
    for team in TEAMS:  # per-image results too
        a = json.loads((out / "teams" / team / "report.json").read_text())["images"]
        b = json.loads((tmp_path / "dask" / "teams" / team / "report.json").read_text())["images"]
        assert _verdicts(a) == _verdicts(b)


# ----------------------------------------------------------------------------- fast teams

FAST_TEAM = """\
from pathlib import Path
Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\\nObstacles: {count}\\nArea: 1.0\\n")
"""


def _fast_teams(root: Path, counts: dict[str, int]) -> Path:
    for name, count in counts.items():
        (root / name).mkdir(parents=True, exist_ok=True)
        (root / name / "map.py").write_text(FAST_TEAM.format(count=count))
    return root


def _opts(**kw) -> GradeOptions:
    return GradeOptions(command=PY_CMD,
                        formats=("json",), settings=grade_settings(), **kw)


@pytest.mark.integration
def test_changed_submission_or_options_are_graded_again(dataset, tmp_path):
    subs = _fast_teams(tmp_path / "subs", {"a": 1, "b": 2, "c": 3})
    out = tmp_path / "out"
    first = grade(dataset, subs, out, options=_opts(), workers=2, allow_guessable_seed=True)
    assert sorted(first.graded) == ["a", "b", "c"] and first.skipped == []
    (subs / "a" / "notes.txt").write_text("a new file")       # content changed: regrade
    (subs / "b" / "__pycache__").mkdir()                       # Python's cache: not content
    (subs / "b" / "__pycache__" / "x.pyc").write_bytes(b"\0")
    os.utime(subs / "c" / "map.py", (0, 0))                    # times only: not content
    second = grade(dataset, subs, out, options=_opts(), workers=2, allow_guessable_seed=True)
    assert second.graded == ["a"] and sorted(second.skipped) == ["b", "c"]
    third = grade(dataset, subs, out, options=_opts(tolerance=0.1), workers=2,
                  allow_guessable_seed=True)
    assert sorted(third.graded) == ["a", "b", "c"]             # other options: regrade all
    # a team removed from SUBMISSIONS leaves the leaderboard
    shutil.rmtree(subs / "c")
    fourth = grade(dataset, subs, out, options=_opts(tolerance=0.1), workers=2,
                   allow_guessable_seed=True)
    assert {r.team for r in fourth.rows} == {"a", "b"}


@pytest.mark.integration
def test_interrupted_grade_keeps_finished_teams(dataset, tmp_path):
    subs = _fast_teams(tmp_path / "subs", {"a": 1, "b": 2, "c": 3})
    out = tmp_path / "out"

    def interrupt(line: str) -> None:
        if ": graded" in line:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        grade(dataset, subs, out, options=_opts(), workers=1, report_workers=1, log=interrupt,
              allow_guessable_seed=True)
    finished = [p.parent.name for p in (out / "teams").glob(f"*/{STATE_FILE}")]
    assert len(finished) == 1
    again = grade(dataset, subs, out, options=_opts(), workers=1, allow_guessable_seed=True)
    assert again.skipped == finished and len(again.graded) == 2
    assert len(again.rows) == 3


@pytest.mark.integration
def test_odd_team_names_are_escaped_and_linked(dataset, tmp_path):
    import html
    import re
    from urllib.parse import unquote

    name = 'we <b>"rock" & ü #1?'
    subs = _fast_teams(tmp_path / "subs", {name: 1, "plain": 2})
    out = tmp_path / "out"
    result = grade(dataset, subs, out, options=_opts(), workers=2, allow_guessable_seed=True)
    assert sorted(result.graded) == sorted([name, "plain"])
    page = (out / "leaderboard.html").read_text()
    assert "<b>" not in page and html.escape(name) in page
    hrefs = re.findall(r'<a href="([^"]+)">', page)
    assert len(hrefs) == 2
    for href in hrefs:  # every link resolves to the team's report
        assert (out / unquote(html.unescape(href))).is_file(), href
    rows = list(csv.DictReader((out / "leaderboard.csv").read_text().splitlines()))
    assert {r["team"] for r in rows} == {name, "plain"}


@pytest.mark.integration
def test_team_folders_named_like_placeholders_are_graded_as_any_other(dataset, tmp_path):
    names = ("x{image}y", "x{submission}y", "plain")
    subs = _fast_teams(tmp_path / "subs", dict.fromkeys(names, 1))
    out = tmp_path / "out"
    result = grade(dataset, subs, out, options=_opts(), workers=2, allow_guessable_seed=True)
    assert sorted(result.graded) == sorted(names) and not result.errors
    reports = {n: json.loads((out / "teams" / n / "report.json").read_text()) for n in names}
    for name in names:  # every image answered (count 1), as the plain team's
        assert [i["category"] for i in reports[name]["images"]] == \
            [i["category"] for i in reports["plain"]["images"]], reports[name]["images"]
        assert {i["pred"]["count"] for i in reports[name]["images"]} == {1}


def test_team_command_substitutes_the_team_folder(tmp_path):
    team = tmp_path / "team with space"
    cmd = team_command("python3 {submission}/map.py --image {image}", team)
    assert cmd == f"python3 '{team}/map.py' --image '{{image}}'"
    pipe = CommandPipeline(cmd, base_dir=str(team))
    assert pipe.argv(Path("/d/x.png"))[1] == f"{team}/map.py"


def test_submission_hash_is_names_and_contents(tmp_path):
    a = _fast_teams(tmp_path / "a", {"t": 1}) / "t"
    b = _fast_teams(tmp_path / "b", {"t": 1}) / "t"
    assert submission_hash(a) == submission_hash(b)
    (b / "sub").mkdir()
    assert submission_hash(a) == submission_hash(b)            # empty folders do not count
    (b / "sub" / "x").write_text("")
    h_file = submission_hash(b)
    assert h_file != submission_hash(a)
    (b / "sub" / "x").rename(b / "sub" / "y")
    assert submission_hash(b) not in (h_file, submission_hash(a))   # names count
    (b / "sub" / "y").unlink()
    (b / "link").symlink_to("/etc/passwd")                    # links: target text, not followed
    h_link = submission_hash(b)
    assert h_link != submission_hash(a)
    os.mkfifo(b / "fifo")                                      # a FIFO must not block
    assert submission_hash(b) != h_link


def _row(team, n_passed, exact, area, latency):
    summary = Summary(n=4, n_passed=n_passed, pass_rate=n_passed / 4, pass_rate_ci95=(0, 1),
                      count_exact_rate=exact, count_mae=None, area_rel_err={"median": area},
                      area_rel_err_signed={}, marker_id_accuracy=None, failures={},
                      latency_ms={"median": latency})
    return LeaderboardRow(team=team, summary=summary, report="", submission_sha256="0" * 64)


def test_ranking_keys_and_deterministic_ties():
    rows = [
        _row("e", 3, 1.0, 0.01, 10.0),
        _row("d", 3, 1.0, 0.01, 99.0),      # tie with e (latency never ranks): by name
        _row("c", 3, 1.0, 0.005, 50.0),     # better area
        _row("b", 3, 1.0, None, 1.0),       # never answered: after any area
        _row("a", 3, 0.75, 0.0, 1.0),       # fewer exact counts
        _row("z", 4, 0.0, 0.5, 99.0),       # more passes first
    ]
    ranked = rank_rows(rows)
    assert [r.team for r in ranked] == ["z", "c", "d", "e", "b", "a"]
    assert [r.rank for r in ranked] == [1, 2, 3, 3, 5, 6]
    assert [r.tied for r in ranked] == [False, False, True, True, False, False]
    # the same rows in any order, with any latencies: the same ranks
    again = rank_rows([_row(r.team, 3, 1.0, 0.01, 1000.0 - i) if r.team in "de" else r
                       for i, r in enumerate(reversed(rows))])
    assert [(r.team, r.rank, r.tied) for r in again] == [(r.team, r.rank, r.tied)
                                                         for r in ranked]


def test_leaderboard_csv_escapes_formulas_and_rounds_floats():
    from arenabench.eval.grade.leaderboard import leaderboard_dict
    from arenabench.eval.grade.leaderboard_report import leaderboard_csv

    rows = rank_rows([_row(name, 3, 0.1 + 0.2, 0.30000000000000004, 1.0)
                      for name in ("=HYPERLINK(1)", "+1", "-2", "@SUM(A1)", "plain")])
    doc = leaderboard_dict(rows, dataset={"path": "d", "manifest_sha256": "0" * 64, "n": 4},
                           options={})
    text = leaderboard_csv(doc)
    cells = list(csv.DictReader(text.splitlines()))
    assert {c["team"] for c in cells} == {"'=HYPERLINK(1)", "'+1", "'-2", "'@SUM(A1)", "plain"}
    assert "0.30000000000000004" not in text and "0.3," in text
    assert all(c["rank"] == "1" for c in cells)  # all equal: one shared rank


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--workers", "0"], "argument --workers: must be an integer in [1, 256], got '0'"),
        (["--timeout", "0"], "argument --timeout: must be a finite number in [1, 86400], got '0'"),
        (["--tolerance", "inf"], "--tolerance"),
        (["--tolerance", "1e309"], "--tolerance"),
        (["--reference", "/nonexistent/ref"], "--reference /nonexistent/ref: not a folder"),
        (["--formats", "html,pdf"], "argument --formats: unknown 'pdf'"),
        (["--cmd", "python3 'unclosed"], "--cmd cannot be split"),
        (["--memory-limit", "lots"], "--memory-limit: not a size"),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "exclude each other"),
    ],
)
def test_bad_options_exit_2_with_one_line(extra, needle, dataset, tmp_path, capsys):
    subs = _fast_teams(tmp_path / "subs", {"a": 1})
    out = tmp_path / "out"
    rc = arenabench_main(["grade", str(dataset), str(subs), "--out", str(out), *extra, *GRADE_ARGS,
                          "--allow-guessable-seed"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and needle in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_bad_inputs_exit_2_naming_them(dataset, tmp_path, capsys):
    subs = _fast_teams(tmp_path / "subs", {"a": 1})
    (tmp_path / "empty").mkdir()
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "mine.txt").write_text("not a grade output")
    cases = [
        ([str(tmp_path / "nope"), str(subs), "--out", str(tmp_path / "o1")], "nope"),
        ([str(dataset), str(tmp_path / "empty"), "--out", str(tmp_path / "o2")],
         "no team folders"),
        ([str(dataset), str(tmp_path / "none"), "--out", str(tmp_path / "o3")], "none"),
        ([str(dataset), str(subs), "--out", str(subs / "a" / "out")], "inside SUBMISSIONS"),
        ([str(dataset), str(subs), "--out", str(tmp_path / "busy")], "not empty"),
    ]
    for argv, needle in cases:
        rc = arenabench_main(["grade", *argv, *GRADE_ARGS])
        err = capsys.readouterr().err.strip()
        assert rc == 2 and needle in err and len(err.splitlines()) == 1, (argv, err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["busy", "empty", "subs"]
    assert sorted(p.name for p in (subs / "a").iterdir()) == ["map.py"]


@pytest.mark.integration
def test_leaderboard_page_sorts_in_headless_chromium(graded, tmp_path):
    from browser import CHROMIUM_FLAGS, find_chromium

    chromium = find_chromium()
    if chromium is None:
        pytest.skip("chromium is not installed (apt-get install -y chromium)")
    out, _ = graded
    page = out / "leaderboard.html"
    text = page.read_text()
    assert "http://" not in text and "https://" not in text and "<link" not in text

    def order(fragment: str) -> list[str]:
        proc = subprocess.run(
            [chromium, *CHROMIUM_FLAGS, f"--user-data-dir={tmp_path / 'profile'}",
             "--dump-dom", page.resolve().as_uri() + fragment],
            capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr[-2000:]
        assert "Uncaught" not in proc.stderr, proc.stderr[-2000:]
        dom = proc.stdout
        rows = dom[dom.index("<tbody>"):dom.index("</tbody>")]
        return [name for _, name in sorted((rows.index(f">{t}</a>"), t) for t in TEAMS)]

    doc = json.loads((out / "leaderboard.json").read_text())
    assert order("") == [t["team"] for t in doc["teams"]]
    assert order("#sort=team") == sorted(TEAMS)
    assert order("#sort=-team") == sorted(TEAMS, reverse=True)
    by_timeouts = order("#sort=-failures_timeout")
    assert by_timeouts[0] == "slow"


@pytest.mark.integration  # imports Dask
def test_unreachable_scheduler_exits_2_before_writing(dataset, tmp_path):
    subs = _fast_teams(tmp_path / "subs", {"a": 1})
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "arenabench", "grade", *GRADE_ARGS, str(dataset), str(subs),
         "--out", str(out),
         "--scheduler", "tcp://127.0.0.1:9", "--allow-guessable-seed"],
        capture_output=True, text=True, timeout=120,
        env={**_env(), "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "1s"})
    err = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and err[-1].startswith("arenabench grade: error: "), err
    assert "127.0.0.1:9" in err[-1]
    assert not out.exists()


@pytest.mark.integration
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_running_commands_and_keeps_finished_teams(sig, dataset, tmp_path):
    subs = _fast_teams(tmp_path / "subs", {"a": 1})
    (subs / "zz_slow").mkdir()
    (subs / "zz_slow" / "map.py").write_text("import time\ntime.sleep(300)\n")
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "arenabench", "grade", str(dataset), str(subs), "--out",
            str(out), "--cmd", PY_CMD, "--workers", "1",
            "--report-workers", "1", "--formats", "json", "--timeout", "300", "--no-progress",
            "--allow-guessable-seed", *GRADE_ARGS]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        for line in proc.stdout:  # team 'a' runs first (teams in name order, one at a time)
            if line.startswith("a: graded"):
                break
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
    finally:
        proc.kill()
    assert proc.returncode == 128 + sig, err
    assert "finished teams stay graded" in err and "Traceback" not in err
    assert (out / "teams" / "a" / STATE_FILE).is_file()
    assert not (out / "teams" / "zz_slow" / STATE_FILE).exists()
    ps = subprocess.run(["ps", "-eo", "args"], capture_output=True, text=True).stdout
    assert str(subs / "zz_slow" / "map.py") not in ps  # the running command was killed


def test_submission_hash_of_a_deep_tree_and_a_huge_sparse_file(tmp_path):
    team = _fast_teams(tmp_path / "subs", {"t": 1}) / "t"
    try:
        _check_deep_tree_and_sparse_file_hash(team, tmp_path)
    finally:  # pytest's own clean-up of old temp folders recurses and would fail on 1500 levels
        subprocess.run(["rm", "-rf", str(team)], check=True)


def _check_deep_tree_and_sparse_file_hash(team, tmp_path):
    fd = os.open(team, os.O_RDONLY | os.O_DIRECTORY)
    for _ in range(1500):  # deeper than Python's recursion limit
        os.mkdir("d", dir_fd=fd)
        fd, old = os.open("d", os.O_RDONLY | os.O_DIRECTORY, dir_fd=fd), fd
        os.close(old)
    os.close(os.open("leaf.txt", os.O_WRONLY | os.O_CREAT, dir_fd=fd))
    os.close(fd)
    h_deep = submission_hash(team)
    assert h_deep != submission_hash(_fast_teams(tmp_path / "other", {"t": 1}) / "t")
    with open(team / "huge.bin", "wb") as fh:  # 1 TiB, sparse: must not be read
        fh.truncate(1 << 40)
    h_huge = submission_hash(team)
    assert h_huge != h_deep and submission_hash(team) == h_huge
    with open(team / "huge.bin", "r+b") as fh:
        fh.truncate((1 << 40) + 1)  # another size: another hash
    assert submission_hash(team) != h_huge


# ------------------------------------------------- giving up on a team, resuming a team half-way

#: A team script that says when it starts (a file ``run-N`` in MARKS: the grades below run
#: with --sandbox none, so it can write there) and then, while the file ``MARKS/hang``
#: exists, from its HANG_FROM-th run on, sleeps; otherwise it answers at once.
MARKED_TEAM = """\
import os, time
marks, hang_from = {marks!r}, {hang_from}
n = len([f for f in os.listdir(marks) if f.startswith("run-")])
open(os.path.join(marks, f"run-{{n}}"), "w").close()
if n >= hang_from and os.path.exists(os.path.join(marks, "hang")):
    time.sleep(300)
open("obstacles.txt", "w").write("Aruco ID: [80, 85, 90, 95]\\nObstacles: 1\\nArea: 1.0\\n")
"""


def _marked_team(subs: Path, name: str, marks: Path, *, hang_from: int) -> Path:
    (subs / name).mkdir(parents=True)
    marks.mkdir(parents=True)
    (marks / "hang").touch()
    (subs / name / "map.py").write_text(MARKED_TEAM.format(marks=str(marks),
                                                           hang_from=hang_from))
    return marks


def _runs(marks: Path) -> int:
    return len(list(marks.glob("run-*")))


@pytest.fixture(scope="module")
def toy8(tmp_path_factory):
    import toy_arena

    return toy_arena.write_toy_dataset(tmp_path_factory.mktemp("toy8") / "toy", n=8, seed=1)


@pytest.mark.integration
def test_a_team_that_times_out_in_a_row_is_given_up(toy8, tmp_path, capsys):
    subs = _fast_teams(tmp_path / "subs", {"a_fast": 1})
    marks = _marked_team(subs, "b_hangs", tmp_path / "marks", hang_from=0)
    out = tmp_path / "out"
    opts = GradeOptions(command=f"{sys.executable} {{submission}}/map.py --image {{image}}",
                        formats=("json",), give_up_after=2,
                        # long enough for the preflight's reference on a busy machine
                        settings=grade_settings(sandbox="none", limits={"timeout_s": 10.0}))
    result = grade(toy8, subs, out, options=opts, workers=1, report_workers=1, log=print,
                   allow_guessable_seed=True)
    assert sorted(result.graded) == ["a_fast", "b_hangs"] and not result.errors
    # images 0 and 1 timed out; image 2 may have started as 1 ended (then it was stopped);
    # the five after it never ran
    assert 2 <= _runs(marks) <= 3
    report = json.loads((out / "teams" / "b_hangs" / "report.json").read_text())
    images = report["images"]
    assert [i["status"] for i in images] == ["timeout"] * 8
    assert all("skipped" not in i["message"] for i in images[:2])
    assert all(i["message"].startswith("skipped: 2 consecutive timeouts before it "
                                       "(000000 to 000001)") for i in images[2:])
    assert report["given_up"] == {"after": 2, "first": "000000", "last": "000001",
                                  "timeouts": 2, "skipped": 6}
    assert report["summary"]["failures"]["timeout"] == 8
    state = json.loads((out / "teams" / "b_hangs" / STATE_FILE).read_text())
    assert state["given_up"]["skipped"] == 6
    said = capsys.readouterr().out
    assert ("b_hangs: giving up after 2 consecutive timeouts (000000 to 000001): 6 later images "
            "not run" in said)
    assert "b_hangs: graded (0/8 passed; gave up after 2 consecutive timeouts" in said
    # the other team is untouched by it
    fast = json.loads((out / "teams" / "a_fast" / "report.json").read_text())
    assert fast["given_up"] is None and len(fast["images"]) == 8


#: A team script that sleeps on the images whose SHA-256 is in HANG and answers the others at
#: once (it sees a copy of the image under another name).
HANGS_ON_IMAGES = """\
import hashlib, sys, time
from pathlib import Path
image = Path(sys.argv[sys.argv.index("--image") + 1])
if hashlib.sha256(image.read_bytes()).hexdigest() in {hang!r}:
    time.sleep(300)
Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\\nObstacles: 1\\nArea: 1.0\\n")
"""


@pytest.mark.integration
def test_giving_up_gives_the_same_verdicts_whatever_the_workers(toy8, tmp_path):
    # images 000001 and 000002 hang; the others answer at once. One worker never starts the
    # images after 000002; four run 000003 to 000007 (and have their answers back) while
    # 000001 and 000002 are still sleeping. The verdicts must not tell the two apart.
    subs = tmp_path / "subs"
    (subs / "hangs").mkdir(parents=True)
    hang = {hashlib.sha256((toy8 / "images" / f"{i}.png").read_bytes()).hexdigest()
            for i in ("000001", "000002")}
    (subs / "hangs" / "map.py").write_text(HANGS_ON_IMAGES.format(hang=hang))
    opts = GradeOptions(command=f"{sys.executable} {{submission}}/map.py --image {{image}}",
                        formats=("json",), give_up_after=2,
                        settings=grade_settings(sandbox="none", limits={"timeout_s": 10.0}))
    reports = []
    for workers in (1, 4):
        out = tmp_path / f"w{workers}"
        result = grade(toy8, subs, out, options=opts, workers=workers, report_workers=1,
                       allow_guessable_seed=True)
        assert result.graded == ["hangs"] and not result.errors
        reports.append(json.loads((out / "teams" / "hangs" / "report.json").read_text()))
    one, four = reports
    assert one["given_up"] == four["given_up"] == {
        "after": 2, "first": "000001", "last": "000002", "timeouts": 2, "skipped": 5}
    assert _verdicts(one["images"]) == _verdicts(four["images"])
    assert [i["status"] for i in four["images"]] == ["ok"] + ["timeout"] * 7
    assert [i["message"].startswith("skipped:") for i in four["images"]] == [False] * 3 + \
        [True] * 5


def test_settling_skips_every_image_after_the_first_run_whatever_ran():
    from arenabench.eval.grade.give_up import settle
    from arenabench.eval.scoring.results import Prediction

    t, ok = Prediction(status="timeout"), Prediction(status="ok", count=1, area=1.0)
    ids = [f"{j:06d}" for j in range(7)]
    # one worker: nothing after image 3 ran; four workers: images 4 and 5 ran, 6 timed out
    few = [ok, t, t, t, None, None, None]
    many = [ok, t, t, t, ok, ok, t]
    settled = []
    for preds in (few, many):
        given_up = settle(preds, 2, ids)
        assert given_up is not None and given_up.to_dict() == {
            "after": 2, "first": "000001", "last": "000002", "timeouts": 2, "skipped": 4}
        settled.append(preds)
    assert settled[0] == settled[1]
    assert settled[0][:3] == [ok, t, t]
    assert all(p.status == "timeout" and p.message.startswith("skipped: 2 consecutive")
               for p in settled[0][3:])
    # no run of timeouts: nothing changes; a missing result without one is the grader's error
    preds = [ok, t, ok, t]
    assert settle(preds, 2, ids[:4]) is None and preds == [ok, t, ok, t]
    assert settle([t, t, t], 0, ids[:3]) is None
    with pytest.raises(ValueError, match="image 000002 has no result"):
        settle([ok, t, None], 2, ids[:3])


def test_consecutive_timeouts_are_counted_in_image_order_whatever_order_they_come_back():
    from arenabench.eval.grade.give_up import first_timeout_run, timeout_run
    from arenabench.eval.scoring.results import Prediction

    t, ok = Prediction(status="timeout"), Prediction(status="ok", count=1, area=1.0)
    preds = [None] * 8
    # results come back out of order (parallel workers): 3, 1, 6, 2
    for j, pred in ((3, t), (1, t), (6, t)):
        preds[j] = pred
        run = timeout_run(preds, j)
        assert run is not None and run[1] - run[0] + 1 < 3  # 1 and 3 are not in a row yet
    preds[2] = t
    assert timeout_run(preds, 2) == (1, 3)  # 1, 2, 3: three in a row
    preds[0] = ok
    assert first_timeout_run(preds, 3) == (1, 3)
    assert first_timeout_run(preds, 4) is None and first_timeout_run(preds, 0) is None
    assert timeout_run(preds, 0) is None


def test_give_up_after_is_refused_when_not_a_count(toy8, tmp_path, capsys):
    subs = _fast_teams(tmp_path / "subs", {"a": 1})
    for bad in ("-1", "two", "1.5"):
        rc = arenabench_main(["grade", str(toy8), str(subs), "--out", str(tmp_path / "o"),
                              "--give-up-after", bad, *GRADE_ARGS, "--allow-guessable-seed"])
        err = capsys.readouterr().err.strip()
        assert rc == 2 and "--give-up-after" in err and len(err.splitlines()) == 1, err
    with pytest.raises(ValueError, match="give_up_after must be an integer"):
        GradeOptions(give_up_after=-1)


@pytest.mark.integration
def test_an_interrupted_team_keeps_its_finished_images_and_resumes_from_there(toy8, tmp_path):
    subs = _fast_teams(tmp_path / "subs", {"a_first": 1})
    marks = _marked_team(subs, "b_stopped", tmp_path / "marks", hang_from=3)
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "arenabench", "grade", str(toy8), str(subs), "--out",
            str(out), "--cmd", f"{sys.executable} {{submission}}/map.py --image {{image}}",
            "--workers", "1", "--report-workers", "1", "--formats", "json,html", "--timeout", "300",
            "--sandbox", "none", "--no-progress", "--allow-guessable-seed", *GRADE_ARGS]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        said: list[str] = []
        import threading

        from hostile_util import wait_for

        reader = threading.Thread(target=lambda: said.extend(proc.stdout), daemon=True)
        reader.start()
        # a is graded (teams run in name order), and b's fourth run hangs: three of its
        # images are done
        assert wait_for(lambda: (any(x.startswith("a_first: graded") for x in said)
                        and _runs(marks) >= 4) or proc.poll() is not None, timeout=300)
        assert proc.poll() is None, said
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=120)
        err = proc.stderr.read()
        reader.join(10)
        stdout = "".join(said)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "b_stopped: not finished: 3 of 8 images done" in stdout, stdout
    doc = json.loads((out / "leaderboard.json").read_text())
    assert doc["complete"] is False and [t["team"] for t in doc["teams"]] == ["a_first"]
    assert doc["unfinished"] == [{"team": "b_stopped", "images_done": 3, "images_total": 8}]
    page = (out / "leaderboard.html").read_text()
    assert "Not finished" in page and "b_stopped (3 of 8 images)" in page
    partial = (out / "teams" / "b_stopped" / "partial-results.jsonl").read_text().splitlines()
    assert len(partial) == 1 + 3  # the header, then images 0, 1, 2
    # resumed (nothing hangs now): b runs only its five other images, a is not run again
    (marks / "hang").unlink()
    again = _grade_cli(str(toy8), str(subs), "--out", str(out), "--cmd",
                       f"{sys.executable} {{submission}}/map.py --image {{image}}",
                       "--workers", "1", "--report-workers", "1", "--formats", "json,html",
                       "--timeout", "300",
                       "--sandbox", "none")  # the same options: a different one grades again
    assert again.returncode == 0, again.stderr
    assert "b_stopped: resuming: 3 of 8 images kept from the last run" in again.stdout
    assert "a_first: skipped: already graded" in again.stdout
    assert _runs(marks) == 4 + 5
    report = json.loads((out / "teams" / "b_stopped" / "report.json").read_text())
    assert [i["id"] for i in report["images"]] == [f"{i:06d}" for i in range(8)]
    assert report["complete"] is True and report["summary"]["n"] == 8
    assert not (out / "teams" / "b_stopped" / "partial-results.jsonl").exists()
    doc = json.loads((out / "leaderboard.json").read_text())
    assert doc["complete"] is True and doc["unfinished"] == []


@pytest.mark.integration
def test_kept_results_are_reused_only_for_the_same_submission(toy8, tmp_path):
    from arenabench.eval.grade.partial import PARTIAL_FILE, PARTIAL_SCHEMA
    from arenabench.eval.grade.seal import sealed

    subs = _fast_teams(tmp_path / "subs", {"a": 1})
    out = tmp_path / "out"
    opts = GradeOptions(command=f"{sys.executable} {{submission}}/map.py --image {{image}}",
                        formats=("json",), settings=grade_settings(sandbox="none"))
    grade(toy8, subs, out, options=opts, workers=1, allow_guessable_seed=True)
    state = json.loads((out / "teams" / "a" / STATE_FILE).read_text())
    header = {k: state[k] for k in ("dataset_manifest_sha256", "options_sha256",
                                    "sandbox_sha256", "team", "submission_sha256")}
    keep = out / "teams" / "a" / PARTIAL_FILE

    def interrupted_before() -> None:
        """What an interrupted grade of 'a' leaves: no state, image 0 kept (an answer the
        script never gives, sealed as grade seals it), image 1's line cut short by a kill;
        and image 2's line written by hand, without a seal."""
        (out / "teams" / "a" / STATE_FILE).unlink()
        line = {"index": 0, "id": "000000",
                "prediction": {"status": "ok", "count": 7, "area": 5.0}}
        forged = {"index": 2, "id": "000002",
                  "prediction": {"status": "ok", "count": 9, "area": 5.0}}
        keep.write_text(json.dumps(sealed({"schema": PARTIAL_SCHEMA, **header})) + "\n"
                        + json.dumps(sealed(line)) + "\n" + json.dumps(forged) + "\n"
                        + '{"index": 1, "id": "0000')

    interrupted_before()
    grade(toy8, subs, out, options=opts, workers=1, allow_guessable_seed=True)
    counts = [i["pred"]["count"] for i in
              json.loads((out / "teams" / "a" / "report.json").read_text())["images"]]
    assert counts == [7] + [1] * 7  # image 0 kept; the forged line and the cut one run again
    assert not keep.exists()
    interrupted_before()
    (subs / "a" / "notes.txt").write_text("changed")  # another submission now
    grade(toy8, subs, out, options=opts, workers=1, allow_guessable_seed=True)
    counts = [i["pred"]["count"] for i in
              json.loads((out / "teams" / "a" / "report.json").read_text())["images"]]
    assert counts == [1] * 8  # nothing kept from another submission
    assert not keep.exists()


@pytest.mark.integration
def test_a_team_given_up_on_a_dask_cluster_has_its_pending_units_cancelled(toy8, tmp_path):
    distributed = pytest.importorskip("distributed")
    subs = tmp_path / "subs"
    marks = _marked_team(subs, "hangs", tmp_path / "marks", hang_from=0)
    opts = GradeOptions(command=f"{sys.executable} {{submission}}/map.py --image {{image}}",
                        formats=("json",), give_up_after=2,
                        settings=grade_settings(sandbox="none", limits={"timeout_s": 10.0}))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  host="127.0.0.1", dashboard_address=None) as cluster:
        result = grade(toy8, subs, tmp_path / "out", options=opts,
                       scheduler=cluster.scheduler_address, allow_guessable_seed=True)
    assert result.graded == ["hangs"]
    assert 2 <= _runs(marks) <= 3  # one unit at a time: the others were cancelled
    report = json.loads((tmp_path / "out" / "teams" / "hangs" / "report.json").read_text())
    assert report["given_up"]["skipped"] == 6
    assert [i["message"].startswith("skipped:") for i in report["images"]] == [False] * 2 + \
        [True] * 6


def test_partial_results_read_back_exactly_and_only_under_their_own_header(tmp_path):
    import math

    from arenabench.eval.grade.partial import PartialLog, read_partial
    from arenabench.eval.scoring.results import Prediction, RunImage

    path = tmp_path / "team" / "partial-results.jsonl"
    header = {"team": "t", "submission_sha256": "a" * 64}
    ids = ["000000", "000001", "000002"]
    # a failing run's thumbnails (bytes) are kept too: the next run's failure card shows them
    thumb = RunImage(name="warped.png", jpeg=b"\xff\xd8\xff\xe0 not JSON text", width=9,
                     height=7)
    odd = Prediction(status="bad_output", count=2, area=float("nan"), marker_ids=(80, 85),
                     message="area is not a number", latency_ms=12.25,
                     obstacles=(((1.5, 2.0), (3.0, 4.0), (5.0, 1.0)),), obstacles_space="image",
                     homography=((1.0, 0.0, 0.5), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
                     run_images=(thumb,))
    log = PartialLog(path, header)
    log.add(2, "000002", odd)
    log.add(0, "000000", Prediction(status="timeout", message="timed out after 60 s"))
    log.close()
    kept = read_partial(path, header, ids)
    assert sorted(kept) == [0, 2] and kept[0].status == "timeout"
    assert math.isnan(kept[2].area) and kept[2] == Prediction(**{**odd.__dict__,
                                                                  "area": kept[2].area})
    # appended to by the next run, after a line a kill cut short
    with open(path, "a") as fh:
        fh.write('{"index": 1, "id": "000')
    again = PartialLog(path, header, append=True)
    again.add(1, "000001", Prediction(status="ok", count=1, area=1.0))
    again.close()
    assert sorted(read_partial(path, header, ids)) == [0, 1, 2]
    # a line naming another image than the set's at its index is not used
    assert sorted(read_partial(path, header, ["000000", "000001", "zzz"])) == [0, 1]
    # another submission: nothing kept, and the file is gone
    assert read_partial(path, {**header, "submission_sha256": "b" * 64}, ids) is None
    assert not path.exists()
