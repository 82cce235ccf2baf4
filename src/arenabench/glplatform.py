"""Choose the OpenGL platform for off-screen rendering before anything imports OpenGL.

PyOpenGL reads ``PYOPENGL_PLATFORM`` once, at import; pyrender otherwise tries pyglet and a
display. :func:`configure` must therefore run before ``import pyrender``. Order of choice:

1. ``PYOPENGL_PLATFORM`` if the user set it;
2. ``egl`` when libEGL and a vendor library (Mesa's ``libEGL_mesa`` or NVIDIA's
   ``libEGL_nvidia``) are present: Mesa llvmpipe on CPU machines, the NVIDIA driver on GPUs;
3. ``osmesa`` when libOSMesa is present;
4. otherwise :class:`GLPlatformError` with the exact packages to install.
"""

from __future__ import annotations

import ctypes.util
import importlib.metadata
import os
import sys
from dataclasses import dataclass

#: Debian/Ubuntu packages that provide EGL off-screen rendering through Mesa (llvmpipe).
EGL_PACKAGES = ("libegl1", "libegl-mesa0", "libgl1-mesa-dri")
#: Debian/Ubuntu package that provides OSMesa.
OSMESA_PACKAGES = ("libosmesa6",)
#: The PyOpenGL release that renders everywhere. pyrender pins 3.1.0, which lacks some OSMesa
#: bindings and cannot render on Python 3.12 or later (its array handlers reject ctypes'
#: argument objects: ``ctypes.ArgumentError`` at the first ``glGenTextures``). With this
#: release the generator's renders are byte-identical to 3.1.0's (docs/commands.md).
PYOPENGL_RELEASE = (3, 1, 7)
#: The requirement that installs it (over pyrender's pin: ``pip install --no-deps``).
PYOPENGL_REQUIREMENT = "PyOpenGL==" + ".".join(map(str, PYOPENGL_RELEASE))
#: PyOpenGL release that has working OSMesa bindings.
OSMESA_PYOPENGL = PYOPENGL_REQUIREMENT
#: The first Python on which pyrender's PyOpenGL 3.1.0 cannot render.
PYOPENGL_310_BROKEN_FROM = (3, 12)
#: The one pyrender release the renderer supports (pinned exactly in pyproject.toml): the
#: generator uses its private API (arenabench.generator.rendering.pyrender_compat checks it on
# import).
PYRENDER_VERSION = "0.1.45"


#: The environment variables :func:`configure` sets for the rest of the process (read once, at
#: the first import of OpenGL and of pyglet).
PROCESS_ENV = ("PYOPENGL_PLATFORM", "PYGLET_HEADLESS")


class GLPlatformError(RuntimeError):
    """No usable off-screen OpenGL platform; the message says what to install."""


@dataclass(frozen=True)
class GLLibraries:
    """Which system OpenGL libraries the dynamic loader can find."""

    egl: str | None
    egl_vendor: str | None
    osmesa: str | None

    @property
    def egl_usable(self) -> bool:
        return self.egl is not None and self.egl_vendor is not None


def find_gl_libraries() -> GLLibraries:
    """Look up libEGL, an EGL vendor library and libOSMesa with the dynamic loader's rules."""
    vendor = ctypes.util.find_library("EGL_mesa") or ctypes.util.find_library("EGL_nvidia")
    return GLLibraries(
        egl=ctypes.util.find_library("EGL"),
        egl_vendor=vendor,
        osmesa=ctypes.util.find_library("OSMesa"),
    )


def install_hint() -> str:
    """The one command that makes EGL off-screen rendering work on Debian/Ubuntu."""
    return "apt-get install -y " + " ".join(EGL_PACKAGES)


def _release(version: str) -> tuple[int, ...]:
    """``"3.1.0"`` -> ``(3, 1, 0)``; a part that is not a number ends the tuple."""
    parts = []
    for part in version.split("."):
        if not part.isdigit():
            break
        parts.append(int(part))
    return tuple(parts)


def pyopengl_problem(installed: str | None = None,
                     python: tuple[int, int] | None = None) -> str | None:
    """Why the installed PyOpenGL cannot render on this Python, or None when it can.

    Parameters
    ----------
    installed : str, optional
        PyOpenGL's version (default: the installed one; None when it is not installed).
    python : tuple of int, optional
        (major, minor) of the interpreter (default: this one).

    Returns
    -------
    str or None
        One line naming both versions and the command that fixes it.
    """
    if installed is None:
        try:
            installed = importlib.metadata.version("PyOpenGL")
        except importlib.metadata.PackageNotFoundError:
            return None  # pyrender's own import says what is missing
    python = tuple(python or sys.version_info[:2])
    if python < PYOPENGL_310_BROKEN_FROM or _release(installed) >= PYOPENGL_RELEASE:
        return None
    return (f"PyOpenGL {installed} (pyrender's pin) cannot render on Python "
            f"{python[0]}.{python[1]}; install {PYOPENGL_REQUIREMENT} over it with: "
            f"pip install --no-deps '{PYOPENGL_REQUIREMENT}'")


def pyopengl_requirement() -> str:
    """The PyOpenGL requirement to install over pyrender's pin here, or ``""`` when none is
    needed (``make`` installs it after the project)."""
    return PYOPENGL_REQUIREMENT if pyopengl_problem() else ""


def choose_platform(libs: GLLibraries | None = None) -> str:
    """Return the platform to use (``"egl"`` or ``"osmesa"`` or the user's choice).

    Raises
    ------
    GLPlatformError
        When neither EGL nor OSMesa is available; the message names the packages.
    """
    user = os.environ.get("PYOPENGL_PLATFORM")
    if user:
        return user
    libs = libs or find_gl_libraries()
    if libs.egl_usable:
        return "egl"
    if libs.osmesa:
        return "osmesa"
    missing = []
    if libs.egl is None:
        missing.append("libEGL.so.1 (package libegl1)")
    if libs.egl_vendor is None:
        missing.append("an EGL vendor library (package libegl-mesa0, or the NVIDIA driver)")
    raise GLPlatformError(
        "no off-screen OpenGL platform: missing " + "; ".join(missing)
        + f". Install with: {install_hint()}  (or, for OSMesa: apt-get install -y "
        + " ".join(OSMESA_PACKAGES) + f" && pip install {OSMESA_PYOPENGL})"
    )


def configure() -> str:
    """Set ``PYOPENGL_PLATFORM`` for this process (if unset) and return it.

    Call before the first ``import pyrender`` / ``import OpenGL``.

    Raises
    ------
    GLPlatformError
        When no platform is available, or OpenGL was already imported with another platform.
    """
    platform = choose_platform()
    current = os.environ.get("PYOPENGL_PLATFORM")
    if "OpenGL" in sys.modules and current != platform:
        raise GLPlatformError(
            "OpenGL was imported before arenabench chose a platform; set "
            f"PYOPENGL_PLATFORM={platform} in the environment or import arenabench first"
        )
    os.environ["PYOPENGL_PLATFORM"] = platform
    if platform == "egl":
        # pyrender imports pyglet's window module (for its viewer) at import; pyglet then
        # loads X11 libraries (libX11, libXrender) that GPU servers and containers often
        # lack, and the import fails. Headless, pyglet uses EGL instead (renders unchanged).
        os.environ.setdefault("PYGLET_HEADLESS", "true")
    return platform
