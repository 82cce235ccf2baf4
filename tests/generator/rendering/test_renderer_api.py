"""The renderer interface and the pyrender boundary: adapters implement
:class:`SceneRenderer`, pyrender's private API stays in ``pyrender_compat``, and any pyrender
release but the pinned one is refused on import with a message naming both versions."""

from __future__ import annotations

import inspect
import json
import re
import subprocess
import sys

import numpy as np
import pytest
from paths import ROOT

from arenabench import doctor
from arenabench.generator.model.sampler import sample_scene
from arenabench.generator.rendering.render import NaiveRenderer, Renderer
from arenabench.generator.rendering.renderer_api import RenderOutput, SceneRenderer
from arenabench.glplatform import PYRENDER_VERSION


@pytest.mark.parametrize("adapter", [Renderer, NaiveRenderer])
def test_adapters_implement_the_interface(adapter):
    assert issubclass(adapter, SceneRenderer)
    assert not adapter.__abstractmethods__
    params = inspect.signature(adapter.render).parameters
    assert list(params) == ["self", "scene", "depth", "masks"]
    assert params["depth"].kind is params["masks"].kind is inspect.Parameter.KEYWORD_ONLY


def test_an_incomplete_adapter_cannot_be_created():
    class NoClose(SceneRenderer):
        def render(self, scene, *, depth=False, masks=False):
            return RenderOutput(rgb=np.zeros((1, 1, 3), np.uint8))

        def gl_info(self):
            return {}

    with pytest.raises(TypeError, match="close"):
        NoClose()


def test_the_pyrender_adapter_renders_through_the_interface():
    scene = sample_scene("eyrc", seed=0, index=0).scene
    renderer: SceneRenderer = Renderer()
    with renderer as r:
        assert r is renderer
        out = r.render(scene, depth=True, masks=True)
        info = r.gl_info()
    assert isinstance(out, RenderOutput)
    assert out.rgb.shape == (scene.camera.height, scene.camera.width, 3)
    assert out.depth.shape == out.instance_mask.shape == out.rgb.shape[:2]
    assert info["gl_renderer"] and info["gl_version"] and info["gl_platform"]
    renderer.close()  # idempotent


# NaiveRenderer's pyrender clean-up terminates the process's EGL display: a process of its own.
_NAIVE = """
import json
from arenabench.generator.rendering.render import NaiveRenderer
from arenabench.generator.model.sampler import sample_scene
scene = sample_scene("eyrc", seed=0, index=0).scene
with NaiveRenderer() as r:
    rgb = r.render(scene).rgb
    try:
        r.render(scene, masks=True)
        refused = ""
    except ValueError as e:
        refused = str(e)
print(json.dumps({"shape": list(rgb.shape), "dtype": str(rgb.dtype),
                  "levels": int(len(set(rgb.reshape(-1, 3)[:, 0].tolist()))),
                  "refused": refused}))
"""


@pytest.mark.integration
def test_the_naive_baseline_renders_through_the_interface():
    proc = subprocess.run([sys.executable, "-c", _NAIVE], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["shape"] == [1000, 1000, 3] and out["dtype"] == "uint8"
    assert out["levels"] > 10  # a lit image, not a blank one
    assert out["refused"].startswith("masks:")


def test_version_check_names_both_versions():
    from arenabench.generator.rendering import pyrender_compat

    pyrender_compat.check_version(PYRENDER_VERSION)
    with pytest.raises(ImportError) as err:
        pyrender_compat.check_version("0.1.44")
    message = str(err.value)
    assert f"pyrender {PYRENDER_VERSION} exactly" in message
    assert "pyrender 0.1.44 is installed" in message
    assert f"pyrender=={PYRENDER_VERSION}" in message


_WRONG_VERSION = """
from arenabench import glplatform
glplatform.configure()
import pyrender
pyrender.__version__ = "0.2.0"
try:
    import arenabench.generator.rendering.pyrender_compat
except ImportError as e:
    print(e)
    raise SystemExit(3)
"""


@pytest.mark.integration
def test_importing_the_compat_module_refuses_another_pyrender_release():
    proc = subprocess.run([sys.executable, "-c", _WRONG_VERSION], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "pyrender 0.2.0 is installed" in proc.stdout
    assert f"pyrender {PYRENDER_VERSION} exactly" in proc.stdout


def test_doctor_flags_another_pyrender_release():
    check = doctor.check_pyrender("0.2.0")
    assert not check.ok
    assert "0.2.0" in check.detail and PYRENDER_VERSION in check.detail
    assert f"pyrender=={PYRENDER_VERSION}" in check.fix


def test_pyproject_pins_the_checked_release():
    text = (ROOT / "pyproject.toml").read_text()
    pins = re.findall(r'"pyrender([<>=!~]=?[^"]*)"', text)
    assert pins == [f"=={PYRENDER_VERSION}"]


#: Signs of pyrender's private API (or its NumPy 2 patch) in source code.
_PRIVATE = re.compile(r"\._egl_|np\.infty|pyrender\.renderer\b|\._renderer\._|\._platform\b")


def test_pyrender_private_api_is_used_only_in_the_compat_module():
    offenders = []
    for folder in ("generator", "eval", "src/arenabench"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel == "generator/rendering/pyrender_compat.py":
                continue
            offenders += [f"{rel}:{n}" for n, line in enumerate(path.read_text().splitlines(), 1)
                          if _PRIVATE.search(line)]
    assert offenders == []


_WITHOUT_SCIPY = """
import sys
from arenabench.generator.rendering.render import Renderer
from arenabench.generator.model.sampler import sample_scene
assert "scipy" not in sys.modules, "pyrender's import loaded SciPy"
with Renderer() as r:
    rgb = r.render(sample_scene("eyrc", seed=0, index=0).scene).rgb
import scipy.spatial  # later imports work as usual
print(rgb.shape, scipy.spatial.ConvexHull([[0, 0], [1, 0], [0, 1]]).volume)
"""


@pytest.mark.integration
def test_pyrender_is_imported_without_scipy_which_stays_importable():
    proc = subprocess.run([sys.executable, "-c", _WITHOUT_SCIPY], capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.split() == ["(1000,", "1000,", "3)", "0.5"]
