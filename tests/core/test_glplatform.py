"""`arenabench.glplatform`: the PyOpenGL release each Python can render with, and a renderer
that starts where no X11 library is installed (real subprocesses, real bubblewrap)."""

import hashlib
import os
import subprocess
import sys

import pytest

from arenabench import doctor, glplatform


@pytest.mark.parametrize(("installed", "python", "broken"), [
    ("3.1.0", (3, 11), False),
    ("3.1.0", (3, 12), True),
    ("3.1.0", (3, 13), True),
    ("3.1.6", (3, 12), True),
    ("3.1.7", (3, 12), False),
    ("3.1.10", (3, 13), False),
    ("3.2.0a1", (3, 14), False),
])
def test_pyrenders_pyopengl_cannot_render_from_python_3_12(installed, python, broken):
    problem = glplatform.pyopengl_problem(installed, python)
    assert (problem is not None) == broken
    if broken:
        assert f"PyOpenGL {installed}" in problem and f"Python {python[0]}.{python[1]}" in problem
        assert f"pip install --no-deps '{glplatform.PYOPENGL_REQUIREMENT}'" in problem


def test_doctor_names_the_pyopengl_release_and_the_fix():
    bad = doctor.check_pyopengl("3.1.0", (3, 12))
    assert not bad.ok and "3.1.0" in bad.detail and "3.12" in bad.detail
    assert bad.fix == f"pip install --no-deps '{glplatform.PYOPENGL_REQUIREMENT}'"
    assert doctor.check_pyopengl("3.1.7", (3, 12)).ok
    assert doctor.check_pyopengl("3.1.0", (3, 11)).ok
    here = doctor.check_pyopengl()
    assert here.ok == (glplatform.pyopengl_problem() is None)


# renders scene 0 of eyrc and prints the hash of its pixels
_RENDER = ("import hashlib; from arenabench.generator import Renderer, make_sample\n"
           "with Renderer() as r:\n"
           "    s = make_sample('eyrc', seed=0, index=0, renderer=r)\n"
           "print(hashlib.sha256(s.render.rgb.tobytes()).hexdigest())\n")


def _library_paths(name: str) -> list[str]:
    """Real paths of the shared library ``name`` in the dynamic loader's cache."""
    out = subprocess.run(["ldconfig", "-p"], capture_output=True, text=True).stdout
    paths = {os.path.realpath(line.split("=>", 1)[1].strip())
             for line in out.splitlines() if line.strip().startswith(name + " ")}
    return sorted(p for p in paths if os.path.exists(p))


@pytest.mark.integration  # a fresh interpreter in a sandbox renders: seconds
def test_the_renderer_starts_where_no_x11_library_is_installed():
    """pyrender imports pyglet's window module, which loads libXrender unless pyglet runs
    headless; GPU servers and containers often have no X11 libraries."""
    from arenabench.eval.runs.sandbox import bwrap_problem

    try:
        platform = glplatform.choose_platform()
    except glplatform.GLPlatformError as exc:
        pytest.skip(f"no off-screen OpenGL here: {exc}")
    if platform != "egl":
        pytest.skip(f"the X11-free start is for EGL; this machine renders with {platform}")
    hidden = _library_paths("libXrender.so.1")
    if not hidden:
        pytest.skip("libXrender is not installed: nothing to hide")
    if (problem := bwrap_problem()) is not None:
        pytest.skip(f"bubblewrap cannot hide a library here: {problem}")
    env = {k: v for k, v in os.environ.items() if k not in ("PYGLET_HEADLESS", "PYOPENGL_PLATFORM")}
    masks = [arg for path in hidden for arg in ("--ro-bind", "/dev/null", path)]
    without = subprocess.run(["bwrap", "--dev-bind", "/", "/", *masks, sys.executable, "-c",
                              _RENDER], capture_output=True, text=True, env=env, timeout=600)
    assert without.returncode == 0, without.stderr[-2000:]
    found = subprocess.run([sys.executable, "-c", _RENDER], capture_output=True, text=True,
                           env=env, timeout=600)
    assert found.returncode == 0, found.stderr[-2000:]
    # the same pixels: headless pyglet changes nothing the renderer draws
    assert without.stdout.split() == found.stdout.split()
    assert len(without.stdout.split()[-1]) == len(hashlib.sha256().hexdigest())
