"""``arenabench doctor``: is this machine ready to detect (OpenCV) and to render (pyrender)?

Checks Python, NumPy, OpenCV with a working ArUco module, pyrender, the OpenGL platform
:mod:`arenabench.glplatform` will choose (EGL or OSMesa) and whether an off-screen context
can actually be created and used; then the sandbox ``grade`` requires (a real bubblewrap run
in new user, PID and network namespaces, the same probe ``grade`` uses) and, as a warning
only, a headless browser (chromium) able to load a page, which the HTML screenshot tests
need. The context is created in a subprocess with a timeout, so a
driver that crashes or hangs cannot take the caller down. Each failed check carries the exact
command that fixes it. Exit status 0 when all is well, 1 otherwise (2 for bad options).
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import os
import subprocess
import sys
from dataclasses import dataclass, field
from typing import Any

from arenabench import glplatform
from arenabench.cliopts import CommandParser, add_timeout
from arenabench.exitcodes import ExitCode
from arenabench.records import to_plain

PROG = "arenabench doctor"
#: Seconds a check that starts a process (the OpenGL context, the sandbox, the browser) may
#: take before it counts as failed (``--timeout``).
CHECK_TIMEOUT_S = 60.0
#: How to install the pinned pyrender release.
PYRENDER_FIX = f"pip install 'pyrender=={glplatform.PYRENDER_VERSION}'"
OPENCV_FIX = (
    "pip uninstall -y opencv-python opencv-python-headless opencv-contrib-python && "
    "pip install 'opencv-contrib-python-headless>=4.8'"
)

# Runs in a child process: choose the platform, import pyrender, render one small scene.
_CONTEXT_PROBE = r"""
import json, sys
from arenabench import glplatform
platform = glplatform.configure()
import numpy as np
from arenabench.generator.rendering.pyrender_compat import pyrender  # its import, checks
import trimesh
from OpenGL import GL
mesh = pyrender.Mesh.from_trimesh(trimesh.creation.box(extents=(1, 1, 1)), smooth=False)
scene = pyrender.Scene(bg_color=[0, 0, 0, 1], ambient_light=[1.0, 1.0, 1.0])
scene.add(mesh)
pose = np.eye(4); pose[2, 3] = 3.0
scene.add(pyrender.PerspectiveCamera(yfov=1.0), pose=pose)
r = pyrender.OffscreenRenderer(64, 48)
color, depth = r.render(scene)
info = {
    "platform": platform,
    "renderer": GL.glGetString(GL.GL_RENDERER).decode("utf-8", "replace"),
    "version": GL.glGetString(GL.GL_VERSION).decode("utf-8", "replace"),
    "shape": list(color.shape),
    "hit_pixels": int((depth > 0).sum()),
}
r.delete()
print("ARENABENCH_PROBE " + json.dumps(info))
"""


@dataclass(frozen=True)
class Check:
    """One line of the report.

    Parameters
    ----------
    name : str
        What was checked.
    ok : bool
        Whether it passed.
    detail : str
        Version or what went wrong.
    fix : str
        The command that fixes it (empty when ok).
    required : bool
        Whether a failure fails the doctor (else it is a warning: ``WARN``).
    """

    name: str
    ok: bool
    detail: str
    fix: str = ""
    required: bool = True

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe form: the fields, in order."""
        return to_plain(self)


@dataclass(frozen=True)
class DoctorReport:
    """All checks, in order."""

    checks: list[Check] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when every required check passed."""
        return all(c.ok for c in self.checks if c.required)

    def to_dict(self) -> dict[str, Any]:
        """JSON-safe form: ``{"ok": bool, "checks": [...]}``."""
        return {"ok": self.ok, "checks": [c.to_dict() for c in self.checks]}

    def to_text(self) -> str:
        """Human-readable report, one line per check plus a fix line per failure."""
        width = max((len(c.name) for c in self.checks), default=0)
        lines = []
        for c in self.checks:
            mark = "ok  " if c.ok else ("FAIL" if c.required else "WARN")
            lines.append(f"{mark}  {c.name:<{width}}  {c.detail}")
            if not c.ok and c.fix:
                lines.append(f"      {'':<{width}}  fix: {c.fix}")
        lines.append("all checks passed" if self.ok else "some checks failed")
        return "\n".join(lines)


def _version(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def check_python() -> Check:
    """Python >= 3.10."""
    v = sys.version_info
    ok = v >= (3, 10)
    return Check("python", ok, f"{v.major}.{v.minor}.{v.micro} ({sys.executable})",
                 "" if ok else "install Python 3.10 or newer")


def check_numpy() -> Check:
    """NumPy importable."""
    try:
        import numpy as np
    except ImportError as exc:
        return Check("numpy", False, f"not importable: {exc}", "pip install numpy")
    return Check("numpy", True, np.__version__)


def check_opencv() -> list[Check]:
    """OpenCV importable, with the ArucoDetector API, and able to find a marker it drew."""
    try:
        import cv2
    except ImportError as exc:
        return [Check("opencv", False, f"not importable: {exc}", OPENCV_FIX)]
    checks = [Check("opencv", True, cv2.__version__)]
    aruco = getattr(cv2, "aruco", None)
    if aruco is None or not hasattr(aruco, "ArucoDetector"):
        checks.append(Check("opencv aruco", False,
                            "cv2.aruco.ArucoDetector missing (OpenCV < 4.7 or no contrib)",
                            OPENCV_FIX))
        return checks
    try:
        import numpy as np

        d = aruco.getPredefinedDictionary(aruco.DICT_4X4_100)
        img = np.full((120, 120), 255, dtype=np.uint8)
        img[30:90, 30:90] = aruco.generateImageMarker(d, 80, 60)
        _, ids, _ = aruco.ArucoDetector(d).detectMarkers(img)
        found = [] if ids is None else [int(i) for i in np.asarray(ids).ravel()]
    except Exception as exc:  # a broken build must be reported, not raised
        return [*checks, Check("opencv aruco", False, f"detection failed: {exc}", OPENCV_FIX)]
    multi = hasattr(aruco.ArucoDetector, "detectMarkersMultiDict")
    ok = found == [80]
    detail = ("detects markers" if ok else f"drew marker 80, detected {found}") + (
        "; multi-dictionary detection available" if multi
        else "; no detectMarkersMultiDict (OpenCV < 4.11): one pass per dictionary"
    )
    checks.append(Check("opencv aruco", ok, detail, "" if ok else OPENCV_FIX))
    return checks


def check_pyrender(installed: str | None = None) -> Check:
    """pyrender installed, the pinned release (not imported here: importing it would fix the
    GL platform).

    Parameters
    ----------
    installed : str, optional
        The release to check; by default the one installed here.
    """
    if installed is None and importlib.util.find_spec("pyrender") is None:
        return Check("pyrender", False, "not installed", PYRENDER_FIX)
    version = installed or _version("pyrender")
    if version is not None and version != glplatform.PYRENDER_VERSION:
        return Check("pyrender", False, f"{version} installed; arenabench needs "
                     f"{glplatform.PYRENDER_VERSION} exactly", PYRENDER_FIX)
    return Check("pyrender", True, version or "installed")


def check_pyopengl(installed: str | None = None, python: tuple[int, int] | None = None) -> Check:
    """PyOpenGL can render on this Python (pyrender's pinned 3.1.0 cannot from Python 3.12).

    Parameters
    ----------
    installed, python : optional
        As :func:`arenabench.glplatform.pyopengl_problem`'s (default: this interpreter's).
    """
    if installed is None:
        installed = _version("PyOpenGL")
        if installed is None:
            return Check("pyopengl", False, "not installed", PYRENDER_FIX)
    problem = glplatform.pyopengl_problem(installed, python)
    if problem:
        return Check("pyopengl", False, problem.split(";")[0],
                     f"pip install --no-deps '{glplatform.PYOPENGL_REQUIREMENT}'")
    return Check("pyopengl", True, installed)


def check_gl_platform() -> tuple[Check, str | None]:
    """Which OpenGL platform :func:`arenabench.glplatform.configure` will use."""
    try:
        platform = glplatform.choose_platform()
    except glplatform.GLPlatformError as exc:
        return Check("opengl platform", False, str(exc), glplatform.install_hint()), None
    libs = glplatform.find_gl_libraries()
    source = "PYOPENGL_PLATFORM" if os.environ.get("PYOPENGL_PLATFORM") else "auto"
    if platform == "osmesa" and libs.osmesa is None:
        return Check("opengl platform", False, f"osmesa ({source}) but libOSMesa is missing",
                     _context_fix("osmesa")), platform
    if platform == "egl" and not libs.egl_usable:
        return Check("opengl platform", False,
                     f"egl ({source}) but libEGL or an EGL vendor library is missing",
                     glplatform.install_hint()), platform
    found = ", ".join(f"{k}={v}" for k, v in (("egl", libs.egl), ("egl_vendor", libs.egl_vendor),
                                                ("osmesa", libs.osmesa)) if v)
    return Check("opengl platform", True, f"{platform} ({source}; {found or 'no libraries'})"), (
        platform
    )


def _context_fix(platform: str | None) -> str:
    if platform == "osmesa":
        return (f"apt-get install -y {' '.join(glplatform.OSMESA_PACKAGES)} && "
                f"pip install {glplatform.OSMESA_PYOPENGL}")
    return (f"{glplatform.install_hint()}  (or try OSMesa: PYOPENGL_PLATFORM=osmesa after "
            f"apt-get install -y {' '.join(glplatform.OSMESA_PACKAGES)} && "
            f"pip install {glplatform.OSMESA_PYOPENGL})")


def check_offscreen_context(platform: str | None, *, timeout: float = CHECK_TIMEOUT_S) -> Check:
    """Create an off-screen context and render one scene, in a subprocess with a timeout."""
    name = "offscreen context"
    if platform is None:
        return Check(name, False, "skipped: no OpenGL platform", _context_fix(None))
    env = dict(os.environ)
    env["PYOPENGL_PLATFORM"] = platform
    try:
        proc = subprocess.run(
            [sys.executable, "-c", _CONTEXT_PROBE],
            capture_output=True, text=True, timeout=timeout, env=env,
        )
    except subprocess.TimeoutExpired:
        return Check(name, False, f"{platform}: no answer within {timeout:g} s (driver hang?)",
                     _context_fix(platform))
    for line in proc.stdout.splitlines():
        if line.startswith("ARENABENCH_PROBE "):
            info = json.loads(line.split(" ", 1)[1])
            ok = info.get("hit_pixels", 0) > 0
            detail = f"{platform}: {info['renderer']} (OpenGL {info['version']})"
            if not ok:
                detail += "; rendered an empty image"
            return Check(name, ok, detail, "" if ok else _context_fix(platform))
    err = [ln for ln in (proc.stderr or "").strip().splitlines() if ln.strip()]
    last = err[-1].strip() if err else f"exit status {proc.returncode}"
    return Check(name, False, f"{platform}: {last[:300]}", _context_fix(platform))


#: How to install bubblewrap (the sandbox of ``grade`` and ``eval --cmd``).
BWRAP_FIX = ("sudo apt-get install -y bubblewrap (and allow unprivileged user namespaces: "
             "sudo sysctl -w kernel.unprivileged_userns_clone=1 "
             "kernel.apparmor_restrict_unprivileged_userns=0)")
#: How to install the headless browser the HTML screenshot tests use.
BROWSER_FIX = "sudo apt-get install -y chromium"
BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
# the harness's own probe (one declaration of the sandbox's namespaces), in a subprocess:
# the core package never imports the harness
_SANDBOX_PROBE = ("from arenabench.eval.runs.sandbox import bwrap_problem; "
                  "print('ARENABENCH_PROBE ' + (bwrap_problem() or 'ok'))")


def check_sandbox(*, timeout: float = CHECK_TIMEOUT_S) -> Check:
    """bubblewrap: a real run in new user, PID and network namespaces (``grade`` refuses
    to run teams without it unless ``--sandbox none``)."""
    import shutil

    name = "sandbox (bubblewrap)"
    exe = shutil.which("bwrap")
    if exe is None:
        return Check(name, False, "bwrap is not installed", BWRAP_FIX)
    try:
        proc = subprocess.run([sys.executable, "-c", _SANDBOX_PROBE], capture_output=True,
                              text=True, timeout=timeout, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return Check(name, False, f"no answer within {timeout:g} s", BWRAP_FIX)
    for line in proc.stdout.splitlines():
        if line.startswith("ARENABENCH_PROBE "):
            why = line.split(" ", 1)[1]
            if why == "ok":
                return Check(name, True, f"{exe}: namespaces work")
            return Check(name, False, why, BWRAP_FIX)
    err = (proc.stderr or "").strip().splitlines() or [f"exit status {proc.returncode}"]
    return Check(name, False, err[-1][:300], BWRAP_FIX)


def check_browser(*, timeout: float = CHECK_TIMEOUT_S) -> Check:
    """A headless browser that loads a page (a warning only: the HTML screenshot tests
    need it, nothing else does)."""
    import shutil
    import tempfile

    name = "headless browser"
    exe = next((p for b in BROWSERS if (p := shutil.which(b))), None)
    if exe is None:
        return Check(name, False, "no chromium found", BROWSER_FIX, required=False)
    with tempfile.TemporaryDirectory(prefix="arenabench-doctor-") as tmp:
        argv = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
                f"--user-data-dir={tmp}", "--dump-dom",
                "data:text/html,<p id=probe>arenabench-doctor</p>"]
        try:
            proc = subprocess.run(argv, capture_output=True, text=True, timeout=timeout,
                                  stdin=subprocess.DEVNULL)
        except (OSError, subprocess.TimeoutExpired) as exc:
            return Check(name, False, f"{exe}: {exc}", BROWSER_FIX, required=False)
    if "arenabench-doctor" in proc.stdout:
        return Check(name, True, f"{exe}: loads a page headless", required=False)
    err = (proc.stderr or "").strip().splitlines() or [f"exit status {proc.returncode}"]
    return Check(name, False, f"{exe}: {err[-1][:300]}", BROWSER_FIX, required=False)


def run_checks(*, context: bool = True, timeout: float = CHECK_TIMEOUT_S) -> DoctorReport:
    """Run every check.

    Parameters
    ----------
    context : bool
        Also create an off-screen OpenGL context (in a subprocess).
    timeout : float
        Seconds the context subprocess may take.
    """
    if timeout <= 0:
        raise ValueError(f"timeout must be > 0, got {timeout!r}")
    renders = [check_pyrender(), check_pyopengl()]
    checks = [check_python(), check_numpy(), *check_opencv(), *renders]
    platform_check, platform = check_gl_platform()
    checks.append(platform_check)
    if context:
        if renders[0].ok:
            checks.append(check_offscreen_context(platform, timeout=timeout))
        else:
            checks.append(Check("offscreen context", False, "skipped: pyrender missing",
                                PYRENDER_FIX))
    checks += [check_sandbox(timeout=timeout), check_browser(timeout=timeout)]
    return DoctorReport(checks)


def build_parser() -> CommandParser:
    """The ``arenabench doctor`` argument parser."""
    parser = CommandParser(
        prog=PROG,
        description="Is this machine ready to detect (OpenCV) and to render (pyrender)? "
        "Checks Python, OpenCV with aruco, pyrender, an off-screen OpenGL context, the "
        "bubblewrap sandbox that 'grade' requires and (a warning only) a headless browser; "
        "exit status 0 when every required check passes, 1 otherwise.")
    parser.add_argument("--json", action="store_true", help="print the report as JSON")
    add_timeout(parser, default=CHECK_TIMEOUT_S,
                help="seconds allowed for creating the OpenGL context")
    parser.add_argument("--no-context", action="store_true",
                        help="skip creating an off-screen OpenGL context")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run ``arenabench doctor``; 0 when all checks pass, 1 otherwise, 2 on bad options."""
    parser = build_parser()
    args = parser.parse_or_status(argv)
    if isinstance(args, int):  # --help (0) or a usage error (2, one line printed)
        return args
    try:
        report = run_checks(context=not args.no_context, timeout=args.timeout)
    except ValueError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return ExitCode.USAGE
    print(json.dumps(report.to_dict(), indent=2) if args.json else report.to_text())
    return ExitCode.OK if report.ok else ExitCode.FAILED


if __name__ == "__main__":
    raise SystemExit(main())
