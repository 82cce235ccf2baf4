"""A scripted round of hostile inputs against ``twin``, ``render`` and ``grade``.

Every case runs the real command in a subprocess (bubblewrap on, as a grading machine has it)
and is judged by what a user would see:

- ``refused``: exit 2 (or the command's own failure status) and one line on stderr naming the
  problem, no traceback, the output folder absent or untouched;
- ``done``: exit 0 and the command's whole output;
- ``stopped``: a case still working at its time cap is sent SIGINT: exit 130 within
  :data:`STOP_GRACE_S` seconds, nothing half-written (a twin of an image it may well fit);
- anything else is a finding: ``traceback``, ``lines`` (a refusal of several lines),
  ``half-written``, ``hang`` (no exit after the stop), ``status`` (an exit status no command
  uses), ``wrong`` (a case's own check failed: a tampered resume state trusted, labels that
  changed with the machine's load).

Usage::

    .venv/bin/python tools/hostile_round.py --out build/hostile-round [--only render,twin]

It writes ``cases.jsonl`` (one record per case) and prints the totals by surface and class.
The figures and the findings fixed go to docs/measurements.md.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from collections import Counter, defaultdict
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT / "tests" / "pipelines"), str(ROOT / "tests")]
PY = sys.executable
EXAMPLE = ROOT.parent / "shared" / "data" / "task1c_image.jpg"
OTHER = ROOT.parent / "shared" / "data" / "other-arenas" / "gg_arena_digital.png"
#: Seconds a case gets before it is sent SIGINT, and then to exit.
CAP_S, STOP_GRACE_S = 40.0, 15.0
#: Exit statuses the commands use (docs/commands.md).
STATUSES = {0, 1, 2, 3, 4, 5, 130, 143}
FAST_TEAM = ('from pathlib import Path\n'
             'Path("obstacles.txt").write_text("Aruco ID: [80, 85, 90, 95]\\nObstacles: 1\\n'
             'Area: 1.0\\n")\n')


@dataclass
class Case:
    """One hostile input: its surface, its name, the command and how it is judged."""

    surface: str
    name: str
    argv: list[str]
    out: Path | None = None
    cap_s: float = CAP_S
    setup: Callable[[], None] | None = None
    expect: str = "refused-or-done"  # or "done", "refused"
    check: Callable[[subprocess.CompletedProcess], str | None] | None = None
    env: dict[str, str] = field(default_factory=dict)


@dataclass
class Outcome:
    surface: str
    name: str
    cls: str
    rc: int | None
    seconds: float
    said: str


def _run(case: Case) -> Outcome:
    if case.setup is not None:
        case.setup()
    before = _listing(case.out)
    start = time.monotonic()
    proc = subprocess.Popen([PY, "-X", "faulthandler", "-m", "arenabench", *case.argv],
                            stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, errors="replace",
                            start_new_session=True, env={**os.environ, **case.env})
    stopped = False
    try:
        out, err = proc.communicate(timeout=case.cap_s)
    except subprocess.TimeoutExpired:
        stopped = True
        os.killpg(proc.pid, signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=STOP_GRACE_S)
        except subprocess.TimeoutExpired:  # where it is stuck: faulthandler's stacks
            os.killpg(proc.pid, signal.SIGABRT)
            try:
                out, err = proc.communicate(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                out, err = proc.communicate()
            where = [x.strip() for x in err.splitlines() if x.strip().startswith("File ")]
            return Outcome(case.surface, case.name, "hang", None,
                           round(time.monotonic() - start, 1), " | ".join(where[:6])[:600])
    seconds = time.monotonic() - start
    rc = proc.returncode
    done = subprocess.CompletedProcess(proc.args, rc, out, err)
    lines = [x for x in err.strip().splitlines() if x.strip()
             and "WARNING" not in x and not x.startswith(("twin: ", "grade: ", "preflight"))]
    said = (lines[-1] if lines else out.strip().splitlines()[-1:] or [""])
    said = said if isinstance(said, str) else said[0]
    cls = _judge(case, rc, err, lines, before, stopped, done)
    return Outcome(case.surface, case.name, cls, rc, round(seconds, 1), said[:300])


def _judge(case: Case, rc: int, err: str, lines: list[str], before: list[str] | None,
           stopped: bool, proc: subprocess.CompletedProcess) -> str:
    if "Traceback (most recent call last)" in err:
        return "traceback"
    if rc not in STATUSES:
        return "status"
    if stopped:
        if rc != 130:
            return "hang"
        return "stopped" if _listing(case.out) == before or _empty(case.out) else "half-written"
    if case.check is not None:
        problem = case.check(proc)
        if problem:
            return "wrong"
    if rc == 0:
        return "done" if case.expect != "refused" else "wrong"
    if case.surface == "grade" and rc == 1:  # some teams not graded, the others are: each
        # refusal one line on stderr, nothing else of the team written
        refusals = [x for x in err.splitlines() if "could not grade" in x]
        return "refused" if refusals and all(x.isprintable() for x in refusals) else "lines"
    if len(lines) != 1:
        return "lines"
    if case.out is not None and _listing(case.out) != before and not _empty(case.out):
        return "half-written"
    return "refused" if case.expect != "done" else "wrong"


def _listing(folder: Path | None) -> list[str] | None:
    if folder is None or not folder.exists():
        return None
    if not folder.is_dir():
        return ["<file>"]
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*")
                  if p.name != ".arenabench.lock")


def _empty(folder: Path | None) -> bool:
    listing = _listing(folder)
    return listing is None or listing == []


# ------------------------------------------------------------------------------ render

def _scene() -> dict:
    from arenabench.generator.model.sampler import sample_scene

    return sample_scene("eyrc", seed=1, index=0).scene.to_dict()


#: Scene fields and the values tried in each.
SCENE_FIELDS = [
    "arena.side_m", "arena.margin_m", "arena.border_width_m", "arena.floor_rgb",
    "arena.grid_step_m", "markers.side_m", "markers.ids", "markers.dictionary",
    "markers.rotation_deg", "camera.width", "camera.height", "camera.fov_deg",
    "camera.altitude_m", "camera.tilt_deg", "camera.yaw_deg", "camera.roll_deg",
    "camera.target_m", "camera.dist", "lighting.ambient", "lighting.directional",
    "obstacles", "obstacles.0.length_m", "obstacles.0.height_m", "obstacles.0.center_m",
    "obstacles.0.yaw_deg", "obstacles.0.color_rgb", "background_rgb", "patches",
]
BAD_VALUES = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf, "neg": -1, "zero": 0,
              "huge": 1e308, "text": "text", "null": None, "true": True, "list": [],
              "dict": {}, "big": 1e6 + 1}


def _set(doc: dict, path: str, value) -> None:
    keys = path.split(".")
    node = doc
    for k in keys[:-1]:
        node = node[int(k)] if isinstance(node, list) else node[k]
    last = keys[-1]
    if isinstance(node, list):
        node[int(last)] = value
    else:
        node[last] = value


def render_cases(root: Path) -> list[Case]:
    cases = []
    base = _scene()

    def scene_case(name: str, doc_or_bytes, *, expect="refused-or-done", check=None,
                   cap=CAP_S) -> Case:
        folder = root / "render" / name
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / "scene.json"
        if isinstance(doc_or_bytes, bytes):
            path.write_bytes(doc_or_bytes)
        else:
            path.write_text(json.dumps(doc_or_bytes))
        return Case("render", name, ["render", str(path), "--out", str(folder / "out")],
                    out=folder / "out", expect=expect, check=check, cap_s=cap)

    for path in SCENE_FIELDS:
        for vname, value in BAD_VALUES.items():
            doc = json.loads(json.dumps(base))
            try:
                _set(doc, path, value)
            except (KeyError, IndexError, TypeError):
                continue
            cases.append(scene_case(f"{path}={vname}", doc))
    # geometry a user could write by mistake, or an attacker on purpose
    d = json.loads(json.dumps(base))
    box = d["obstacles"][0]
    d["obstacles"] = [dict(box) for _ in range(100_000)]
    cases.append(scene_case("100000-boxes", d, expect="refused"))
    d = json.loads(json.dumps(base))
    d["obstacles"] = [dict(box) for _ in range(1001)]
    cases.append(scene_case("1001-boxes", d, expect="refused"))
    d = json.loads(json.dumps(base))
    d["obstacles"] = [dict(box) for _ in range(1000)]
    cases.append(scene_case("1000-boxes", d, cap=120))
    d = json.loads(json.dumps(base))
    d["camera"]["altitude_m"] = -3.0
    cases.append(scene_case("camera-under-floor", d, expect="refused"))
    d = json.loads(json.dumps(base))
    d["obstacles"][0]["height_m"] = d["camera"].get("altitude_m", 3.0) + 1
    cases.append(scene_case("box-above-camera", d, expect="refused"))
    for field_name in ("length_m", "width_m", "height_m"):
        d = json.loads(json.dumps(base))
        d["obstacles"][0][field_name] = -0.5
        cases.append(scene_case(f"negative-{field_name}", d, expect="refused"))
    from arenabench.generator.model.layout import marker_square
    from arenabench.generator.model.scene import Scene

    scene = Scene.from_dict(base)
    over = []
    for corner in ("nw", "ne", "se", "sw"):
        x0, x1, y0, y1 = marker_square(scene.arena, scene.markers, corner)
        over.append({**box, "center_m": [(x0 + x1) / 2, (y0 + y1) / 2],
                     "length_m": 1.3 * (x1 - x0), "width_m": 1.3 * (y1 - y0), "yaw_deg": 0.0})
    d = json.loads(json.dumps(base))
    d["obstacles"] = over

    def covered(proc) -> str | None:
        gt_file = root / "render" / "boxes-over-markers" / "out" / "gt" / "000000.json"
        gt = json.loads(gt_file.read_text())
        return None if not any(m["visible"] for m in gt["markers"]) else "markers visible"

    cases.append(scene_case("boxes-over-markers", d, expect="done", check=covered))
    big = json.dumps({**base, "pad": "x" * (50 << 20)}).encode()
    cases.append(scene_case("50MB-file", big, expect="refused"))
    cases.append(scene_case("deep-nesting", b"[" * 200_000 + b"]" * 200_000, expect="refused"))
    cases.append(scene_case("not-json", b"\x89PNG\r\n\x1a\n" + os.urandom(256),
                            expect="refused"))
    cases.append(scene_case("empty", b"", expect="refused"))
    cases.append(scene_case("array", b"[1, 2, 3]", expect="refused"))
    cases.append(scene_case("bom", b"\xef\xbb\xbf" + json.dumps(base).encode()))
    cases.append(scene_case("utf16", json.dumps(base).encode("utf-16"), expect="refused"))
    cases.append(scene_case("unknown-key", {**base, "extra": 1}, expect="refused"))
    for target in ("/etc/passwd", "/dev/zero", "/nonexistent.png", "/proc/self/mem"):
        d = json.loads(json.dumps(base))
        d["arena"]["texture"] = "image"
        d["arena"]["texture_file"] = target
        d["arena"]["texture_size_m"] = [4.0, 4.0]
        cases.append(scene_case(f"texture-{target.replace('/', '_')}", d, expect="refused"))
    fifo_dir = root / "render" / "fifo"
    fifo_dir.mkdir(parents=True, exist_ok=True)
    fifo = fifo_dir / "scene.json"
    if not fifo.exists():
        os.mkfifo(fifo)
    cases.append(Case("render", "fifo", ["render", str(fifo), "--out", str(fifo_dir / "out")],
                      out=fifo_dir / "out", expect="refused"))
    cases.append(Case("render", "folder", ["render", str(root), "--out",
                                           str(root / "render" / "folder-out")],
                      out=root / "render" / "folder-out", expect="refused"))
    return cases


# ------------------------------------------------------------------------------ twin

def _png_header(width: int, height: int) -> bytes:
    import struct
    import zlib

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    chunk = b"IHDR" + ihdr
    return (b"\x89PNG\r\n\x1a\n" + struct.pack(">I", len(ihdr)) + chunk
            + struct.pack(">I", zlib.crc32(chunk)) + b"\x00" * 64)


def _markers_image(ids, dictionary, *, size=1000, dictionary2=None) -> np.ndarray:
    img = np.full((size, size), 200, np.uint8)
    side = size // 8
    spots = [(40, 40), (size - 40 - side, 40), (size - 40 - side, size - 40 - side),
             (40, size - 40 - side), (size // 2 - side // 2, 40),
             (size - 40 - side, size // 2 - side // 2), (size // 2 - side // 2,
                                                         size - 40 - side),
             (40, size // 2 - side // 2)]
    for k, (i, (x, y)) in enumerate(zip(ids, spots, strict=False)):
        name = dictionary2 if dictionary2 and k % 2 else dictionary
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))
        img[y:y + side, x:x + side] = cv2.aruco.generateImageMarker(d, i, side)
    return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)


def twin_cases(root: Path) -> list[Case]:
    from PIL import Image

    folder = root / "twin"
    folder.mkdir(parents=True, exist_ok=True)
    example = cv2.imread(str(EXAMPLE))
    images: dict[str, Path] = {}

    def put(name: str, data) -> None:
        path = folder / name
        if isinstance(data, bytes):
            path.write_bytes(data)
        elif isinstance(data, np.ndarray):
            cv2.imwrite(str(path), data)
        else:
            data(path)
        images[name] = path

    put("text.png", b"hello, I am not an image\n")
    put("empty.jpg", b"")
    put("random.png", os.urandom(4096))
    put("truncated.jpg", EXAMPLE.read_bytes()[:5000])
    put("truncated.png", cv2.imencode(".png", example)[1].tobytes()[:20000])
    put("pdf.png", b"%PDF-1.4\n" + os.urandom(512))
    put("1x1.png", np.zeros((1, 1, 3), np.uint8))
    put("1x1.jpg", np.zeros((1, 1, 3), np.uint8))
    put("2x2.png", np.zeros((2, 2, 3), np.uint8))
    put("30000-header.png", _png_header(30000, 30000))
    put("8193-header.png", _png_header(8193, 10))
    put("white.png", np.full((480, 640, 3), 255, np.uint8))
    put("black.jpg", np.zeros((480, 640, 3), np.uint8))
    put("noise.png", np.random.default_rng(0).integers(0, 256, (480, 640, 3), np.uint8))
    put("grey.png", cv2.cvtColor(example, cv2.COLOR_BGR2GRAY))
    put("16bit.png", example.astype(np.uint16) * 257)
    put("cmyk.jpg", lambda p: Image.open(EXAMPLE).convert("CMYK").save(p, "JPEG"))
    put("palette.png", lambda p: Image.open(EXAMPLE).convert("P").save(p, "PNG"))
    put("rgba.png", cv2.cvtColor(example, cv2.COLOR_BGR2BGRA))
    put("mirrored.png", example[:, ::-1])
    put("flipped.png", example[::-1])
    put("rot90.png", cv2.rotate(example, cv2.ROTATE_90_CLOCKWISE))
    put("rot180.png", cv2.rotate(example, cv2.ROTATE_180))
    m = cv2.getRotationMatrix2D((example.shape[1] / 2, example.shape[0] / 2), 45, 0.7)
    put("rot45.png", cv2.warpAffine(example, m, example.shape[1::-1]))
    put("upscaled2.png", cv2.resize(example, None, fx=2, fy=2))
    put("downscaled4.png", cv2.resize(example, None, fx=0.25, fy=0.25))
    put("blur3.png", cv2.GaussianBlur(example, (0, 0), 3))
    put("blur12.png", cv2.GaussianBlur(example, (0, 0), 12))
    put("jpeg-q5.jpg", lambda p: cv2.imwrite(str(p), example, [cv2.IMWRITE_JPEG_QUALITY, 5]))
    put("3-markers.png", _markers_image([80, 85, 90], "DICT_4X4_250"))
    put("8-markers.png", _markers_image([10, 11, 12, 13, 14, 15, 16, 17], "DICT_4X4_50"))
    put("2-dictionaries.png", _markers_image([1, 2, 3, 4], "DICT_4X4_50",
                                             dictionary2="DICT_6X6_250"))
    put("dup-ids.png", _markers_image([7, 7, 7, 7], "DICT_4X4_50"))
    if OTHER.is_file():
        put("geo-guide.png", cv2.imread(str(OTHER)))
    link = folder / "loop.png"
    if not link.is_symlink():
        link.symlink_to(link)
    images["loop.png"] = link
    images["dev-zero.png"] = Path("/dev/zero")
    images["folder.png"] = folder
    cases = []
    for name, path in images.items():
        out = folder / f"out-{name}"
        cases.append(Case("twin", name, ["twin", str(path), "--out", str(out), "--no-progress"],
                          out=out))
    # hostile --out with a good image: refused before any work, never written elsewhere
    for name, out in (("out-root", Path("/")), ("out-proc", Path("/proc/arenabench")),
                      ("out-file", folder / "text.png"), ("out-under-file",
                                                          folder / "text.png" / "x"),
                      ("out-newline", folder / "a\nb"), ("out-dev-null", Path("/dev/null"))):
        cases.append(Case("twin", name, ["twin", str(EXAMPLE), "--out", str(out),
                                         "--no-progress"], out=None, expect="refused"))
    return cases


# ------------------------------------------------------------------------------ grade

def _toy(root: Path) -> Path:
    import toy_arena

    data = root / "toy"
    if not data.exists():
        toy_arena.write_toy_dataset(data, n=3, seed=1)
    return data


def _grade_argv(data: Path, subs: Path, out: Path, *extra: str) -> list[str]:
    return ["grade", str(data), str(subs), "--out", str(out), "--cmd",
            f"{PY} {{submission}}/map.py --image {{image}}", "--workers", "1",
            "--report-workers", "1", "--formats", "json", "--timeout", "60",
            "--allow-guessable-seed", "--no-progress", *extra]


def grade_cases(root: Path) -> list[Case]:
    base = root / "grade"
    base.mkdir(parents=True, exist_ok=True)
    data = _toy(base)
    cases = []
    names = {"newline": "a\nb", "dotdot": "..", "dot": ".x", "unicode": "équipe-蛇",
             "space": "team one", "dash": "-rf", "long": "t" * 300, "tab": "a\tb",
             "backslash": "a\\b", "quote": "a'b\"c", "nul-like": "a%00b", "emoji": "🙂",
             "html": "<script>x</script>", "ansi": "\x1b[31mred"}
    for key, name in names.items():
        subs = base / f"names-{key}"

        def make(subs=subs, name=name) -> None:
            _submissions(subs)
            try:  # some names cannot be made ("..", 300 characters): then only "plain" is
                (subs / name).mkdir()
                (subs / name / "map.py").write_text(FAST_TEAM)
            except OSError:
                pass

        out = base / f"out-names-{key}"
        cases.append(Case("grade", f"team-name-{key}", _grade_argv(data, subs, out), out=out,
                          setup=make))
    # a submission folder that is a link to /, to /etc, a team with a 2 GB file, a team with
    # 100,000 files, a team holding a FIFO, a link to /etc/shadow, an unreadable file
    specials: dict[str, Callable[[Path], None]] = {
        "link-to-root": lambda t: t.symlink_to("/"),
        "link-to-etc": lambda t: t.symlink_to("/etc"),
        "2GB-file": lambda t: (t.mkdir(), (t / "map.py").write_text(FAST_TEAM),
                               os.truncate(_touch(t / "weights.bin"), 2 << 30)),
        "100000-files": lambda t: (t.mkdir(), (t / "map.py").write_text(FAST_TEAM),
                                   [(t / f"f{i:06d}").touch() for i in range(100_000)]),
        "fifo-inside": lambda t: (t.mkdir(), (t / "map.py").write_text(FAST_TEAM),
                                  os.mkfifo(t / "pipe")),
        "link-to-shadow": lambda t: (t.mkdir(), (t / "map.py").write_text(FAST_TEAM),
                                     (t / "shadow").symlink_to("/etc/shadow")),
        "map-is-folder": lambda t: (t.mkdir(), (t / "map.py").mkdir()),
        "no-map": lambda t: t.mkdir(),
        "deep-folders": lambda t: (t.mkdir(), (t / "map.py").write_text(FAST_TEAM),
                                   (t / ("d/" * 200)).mkdir(parents=True)),
    }
    for key, make_team in specials.items():
        subs = base / f"special-{key}"

        def make(subs=subs, make_team=make_team) -> None:
            _submissions(subs)
            make_team(subs / "team")

        out = base / f"out-special-{key}"
        cases.append(Case("grade", f"team-{key}", _grade_argv(data, subs, out), out=out,
                          setup=make, cap_s=180))
    cases += _resume_cases(base, data)
    return cases


def _submissions(subs: Path) -> None:
    """A fresh submissions folder holding one plain team that answers at once."""
    if subs.exists():
        shutil.rmtree(subs)
    (subs / "plain").mkdir(parents=True)
    (subs / "plain" / "map.py").write_text(FAST_TEAM)


def _touch(path: Path) -> Path:
    path.touch()
    return path


def _leaderboard(out: Path) -> list:
    doc = json.loads((out / "leaderboard.json").read_text())
    return [{k: v for k, v in t.items() if k not in ("latency_ms_median",)}
            for t in doc["teams"]]


#: How a kept resume state is tampered with between a stop and the resume.
TAMPER = {
    "flip-answer": lambda p: p.write_text(p.read_text().replace('"count":1', '"count":7')),
    "flip-status": lambda p: p.write_text(p.read_text().replace('"ok"', '"timeout"')),
    "garbage-line": lambda p: p.write_text(p.read_text() + "{not json\n"),
    "header-changed": lambda p: p.write_text(
        p.read_text().replace('"team": "b"', '"team": "a"', 1)),
    "truncated": lambda p: p.write_text(p.read_text()[: len(p.read_text()) // 2]),
    "link-to-passwd": lambda p: (p.unlink(missing_ok=True), p.symlink_to("/etc/passwd")),
    "huge": lambda p: os.truncate(p, 200 << 20),
    "folder": lambda p: (p.unlink(), p.mkdir()),
    "fifo": lambda p: (p.unlink(), os.mkfifo(p)),
    "extra-images": lambda p: p.write_text(p.read_text() + p.read_text().splitlines()[-1]
                                           .replace('"index": 1', '"index": 5') + "\n"),
    "state-forged": None,  # team a's grade-state.json edited: another submission's
}
#: Team b of the resume cases: hangs on the image whose sha256 the file HANG names.
HANGING_TEAM = (FAST_TEAM + "import hashlib, sys, time\n"
                "image = sys.argv[sys.argv.index('--image') + 1]\n"
                "mark = Path({mark!r})\n"
                "if mark.exists() and hashlib.sha256(open(image, 'rb').read()).hexdigest()"
                " == mark.read_text():\n    time.sleep(600)\n")


def _stop_grade_midway(base: Path, data: Path, subs: Path, out: Path) -> None:
    """Start a grade, SIGINT it once team b has three partial lines (or it ended), and wait
    for it (SIGABRT for faulthandler's stacks in the log when it does not stop)."""
    log = open(base / f"stop-{out.name}.log", "w")
    proc = subprocess.Popen([PY, "-X", "faulthandler", "-m", "arenabench",
                             *_grade_argv(data, subs, out, "--sandbox", "none")],
                            stdout=log, stderr=log)
    partial = out / "teams" / "b" / "partial-results.jsonl"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None:
        if partial.is_file() and len(partial.read_text().splitlines()) >= 3:
            break
        time.sleep(0.1)
    lines = len(partial.read_text().splitlines()) if partial.is_file() else None
    log.write(f"\n## SIGINT after {time.monotonic() - deadline + 300:.1f} s, partial "
              f"{lines} lines, running {proc.poll() is None}\n")
    log.flush()
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=60)
    except subprocess.TimeoutExpired:  # where it is: faulthandler's stacks in the log
        proc.send_signal(signal.SIGABRT)
        proc.wait()
        raise
    finally:
        log.close()


def _tampered(out: Path, tamper) -> None:
    """Edit the stopped grade's resume state: team a's verdicts (``tamper`` None), or team
    b's partial results with ``tamper``."""
    if tamper is None:
        state = out / "teams" / "a" / "grade-state.json"
        doc = json.loads(state.read_text())
        doc["summary"]["n_passed"] = doc["summary"].get("n", 3)
        doc["summary"]["pass_rate"] = 1.0
        state.write_text(json.dumps(doc))
    else:
        tamper(out / "teams" / "b" / "partial-results.jsonl")


def _resume_cases(base: Path, data: Path) -> list[Case]:
    """A grade stopped (its resume state kept: team a graded, b two images in, hanging on
    the third) and resumed after tampering with the state: the resumed leaderboard must equal
    an uninterrupted grade's, or the resume be refused in one line."""
    import hashlib

    mark = base / "HANG"
    subs = base / "resume-subs"
    if not subs.exists():
        for name in ("a", "b"):
            (subs / name).mkdir(parents=True)
        (subs / "a" / "map.py").write_text(FAST_TEAM)
        (subs / "b" / "map.py").write_text(HANGING_TEAM.format(mark=str(mark)))
    third = sorted((data / "images").iterdir())[2]
    sha = hashlib.sha256(third.read_bytes()).hexdigest()
    none = ("--sandbox", "none")
    reference = base / "resume-reference"

    def clear(out: Path) -> None:
        if out.exists():
            shutil.rmtree(out)
        mark.unlink(missing_ok=True)

    cases = [Case("grade", "resume-reference", _grade_argv(data, subs, reference, *none),
                  out=None, expect="done", setup=lambda: clear(reference))]
    for key, tamper in TAMPER.items():
        out = base / f"resume-{key}"

        def setup(out=out, tamper=tamper) -> None:
            clear(out)
            mark.write_text(sha)
            _stop_grade_midway(base, data, subs, out)
            mark.unlink()
            _tampered(out, tamper)

        def same(proc, out=out) -> str | None:
            if proc.returncode != 0:
                return None  # a refusal is judged as one
            return None if _leaderboard(out) == _leaderboard(reference) else "leaderboard moved"

        cases.append(Case("grade", f"resume-{key}", _grade_argv(data, subs, out, *none),
                          out=None, setup=setup, check=same, cap_s=120))
    out = base / "two-grades"
    held: list[subprocess.Popen] = []

    def first_grade(out=out) -> None:
        clear(out)
        mark.write_text(sha)  # the first grade hangs on team b's third image: it holds --out
        held.append(subprocess.Popen([PY, "-m", "arenabench",
                                      *_grade_argv(data, subs, out, *none)],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not (out / ".arenabench.lock").exists():
            time.sleep(0.1)

    def second_refused(proc) -> str | None:
        for p in held:
            p.send_signal(signal.SIGINT)
            p.wait(timeout=60)
        mark.unlink(missing_ok=True)
        return None if proc.returncode == 2 and "another run" in proc.stderr else "not locked"

    cases.append(Case("grade", "two-grades-one-out", _grade_argv(data, subs, out, *none),
                      out=None, setup=first_grade, check=second_refused, expect="refused"))
    return cases


def _labels(out: Path) -> dict:
    """Each team's verdicts and phase labels, without wall-clock fields."""
    labels = {}
    for team in sorted((out / "teams").iterdir()):
        report = json.loads((team / "report.json").read_text())
        labels[team.name] = [(im["id"], im["pass"], im.get("category"),
                              (im.get("phase") or {}).get("class"))
                             for im in report["images"]]
    return labels


def load_cases(root: Path) -> list[Case]:
    """A 3-team grade with the phase check on, idle and beside two CPU burners: the same
    verdicts and labels."""
    base = root / "load"
    base.mkdir(parents=True, exist_ok=True)
    data = base / "set"
    if not data.exists():
        subprocess.run([PY, "-m", "arenabench", "generate", "--preset", "eyrc", "--count", "6",
                        "--seed", "31", "--out", str(data), "--no-progress"], check=True,
                       capture_output=True)
    subs = base / "subs"
    if not subs.exists():
        pipes = ROOT / "tests" / "pipelines"
        for name, script in (("canny", "style_canny.py"), ("grey_band", "style_grey_band.py"),
                             ("reference", None)):
            (subs / name).mkdir(parents=True)
            text = ("import sys\nfrom arenabench.detect import main\n"
                    "sys.exit(main(sys.argv[1:]))\n") if script is None else (
                (pipes / script).read_text())
            (subs / name / "map.py").write_text(text)
    idle, busy = base / "idle", base / "busy"
    argv = ["grade", str(data), str(subs), "--cmd",
            f"{PY} {{submission}}/map.py --image {{image}}", "--phase-check", "4",
            "--formats", "json", "--allow-guessable-seed", "--no-progress", "--workers", "2",
            "--sandbox", "none", "--env", f"PYTHONPATH={ROOT / 'tests' / 'pipelines'}"]

    def clear() -> None:
        for out in (idle, busy):
            if out.exists():
                shutil.rmtree(out)

    def same(proc) -> str | None:
        if proc.returncode != 0:
            return "not graded"
        with_burners = subprocess.run(
            [PY, str(ROOT / "tools" / "with_burners.py"), "--burners", "2", "--", PY, "-m",
             "arenabench", *argv, "--out", str(busy)], capture_output=True, text=True)
        if with_burners.returncode != 0:
            return f"busy grade exit {with_burners.returncode}: {with_burners.stderr[-200:]}"
        return None if _labels(idle) == _labels(busy) else "labels moved with the load"

    return [Case("load", "3-teams-phase-check-idle-and-busy", [*argv, "--out", str(idle)],
                 setup=clear, check=same, expect="done", cap_s=900)]


SURFACES = {"render": render_cases, "twin": twin_cases, "grade": grade_cases,
            "load": load_cases}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=ROOT / "build" / "hostile-round")
    p.add_argument("--only", default=",".join(SURFACES))
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--cases", default="", help="only the cases whose name holds this text")
    args = p.parse_args(argv)
    # a background job of a non-interactive shell ignores SIGINT, and so would every command
    # it starts (arenabench keeps an inherited SIG_IGN): the stops below must reach them
    signal.signal(signal.SIGINT, signal.default_int_handler)
    args.out = args.out.resolve()  # the cases run commands from elsewhere too
    args.out.mkdir(parents=True, exist_ok=True)
    cases = [c for s in args.only.split(",") for c in SURFACES[s](args.out / "inputs")
             if args.cases in c.name]
    print(f"{len(cases)} cases", flush=True)
    outcomes = []
    # grade's cases in order on one worker (the resume cases compare with the reference, the
    # two grades share a marker file); the others side by side
    serial = [c for c in cases if c.surface in ("grade", "load")]
    parallel = [c for c in cases if c.surface not in ("grade", "load")]
    with (ThreadPoolExecutor(args.workers) as pool,
          open(args.out / "cases.jsonl", "w") as log):
        for o in itertools.chain(map(_safe, serial), pool.map(_safe, parallel)):
            outcomes.append(o)
            log.write(json.dumps(asdict(o)) + "\n")
            log.flush()
            if o.cls not in ("refused", "done", "stopped"):
                print(f"FINDING {o.surface} {o.name!r}: {o.cls} (rc {o.rc}): {o.said}",
                      flush=True)
    table: dict[str, Counter] = defaultdict(Counter)
    for o in outcomes:
        table[o.surface][o.cls] += 1
    classes = sorted({c for t in table.values() for c in t})
    print("surface  " + "  ".join(f"{c:>12}" for c in classes) + "         all")
    for s, t in table.items():
        print(f"{s:<8} " + "  ".join(f"{t[c]:>12}" for c in classes) + f"  {sum(t.values()):>10}")
    return 0


def _safe(case: Case) -> Outcome:
    try:
        return _run(case)
    except Exception as exc:  # the round's own failure: said, not hidden
        return Outcome(case.surface, case.name, "setup-error", None, 0.0,
                       f"{type(exc).__name__}: {exc}"[:300])


if __name__ == "__main__":
    raise SystemExit(main())
