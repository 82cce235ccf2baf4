"""One call from (preset, seed, index) to an image and its ground truth, in memory.

The image recipe is one function, :func:`scene_image`: ``scene -> render -> [degrade] ->
encode`` (the preset's ``output.*``, :class:`ImageFormat`) and the GT record. Everything that
makes an image of a scene goes through it: :func:`make_sample` (the dataset writer, sweeps,
contact sheets) after drawing the scene, and the phase check on its moved scenes, so a
re-rendered image is encoded exactly as the set's own. Streaming sweeps use this directly with
one :class:`~arenabench.generator.rendering.render.Renderer` per process (any
:class:`~arenabench.generator.rendering.renderer_api.SceneRenderer` will do).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import cv2
import numpy as np

from arenabench.fileio import rounded
from arenabench.frame import FrameSpec
from arenabench.generator.model.sampler import sample_scene, stream_rng
from arenabench.generator.parameters.params import Range, Value
from arenabench.generator.parameters.presets import preset_name as _name_of
from arenabench.generator.parameters.presets import resolve
from arenabench.generator.rendering.degrade import Degradations, apply_degradations
from arenabench.generator.rendering.render import Renderer
from arenabench.generator.rendering.renderer_api import RenderOutput, SceneRenderer
from arenabench.generator.truth.groundtruth import compute_ground_truth
from arenabench.generator.truth.scene_facts import derived_facts
from arenabench.gtrecord import GroundTruth
from arenabench.imageio import DEFAULT_JPEG_SUBSAMPLING, IMAGE_EXTENSIONS, encode_image
from arenabench.schemas import GT_SCHEMA
from arenabench.workers import thread_state

#: Bumped whenever the same (preset, seed, index) would give different images or GT.
#: 2: degradation / scene-variation parameters recorded in the GT's params and
#: scene, per-marker occlusion fields, "homography_domain"; images unchanged.
#: 3: textures sampled bilinearly in the nearest mip level (mean change 0.1 grey level, ~20 %
#: faster renders); Gaussian noise drawn with OpenCV's sampler; eyrc re-tuned so that the
#: fitted competition example lies inside it (marker side, fov, altitude, light); any other
#: range-valued parameter drawn from its own stream; warehouse preset.
#: 4: `eyrc` is the hidden-test twin (the competition's arena texture, the refitted example's
#: camera, light and box grey fixed, boxes axis-aligned); the former eyrc is `eyrc-jitter`
#: (eyrc-upright, -oblique, -hard and warehouse build on it); 4x MSAA colour pass on every
#: preset; scene files state the camera one way; GT ``area.contour_px`` (what
#: cv2.contourArea of the pixelated visible silhouettes gives); meshes drawn in a fixed order
#: (obstacles, floor overlays, markers, floor): where a box side meets the floor their depths
#: can tie in a pixel, and which one won used to depend on memory addresses, so 1-2 % of
#: images differed in a pixel from run to run, on every preset.
#: 5: draws keyed by name: every parameter is drawn from a random stream of its own, seeded by
#: (seed, index, crc32(name)), and so are obstacle placement, warehouse loads, floor patches and
#: image noise (they were drawn in list order from three shared generators); every preset's
#: sampled values, hence images and GT, differ. Parameters are declared once
#: (generator/parameters/params.py). Edges as the competition's renderer draws them: two samples per
#: pixel (a quarter pixel either side of the centre, on the diagonal) averaged in linear light
#: on the obstacles' region, instead of 4x MSAA averaged in sRGB (docs/rendering.md); images
#: change along box outlines only.
#: 6: (a) textures sampled as ogre2 samples a diffuse map: stored as sRGB, the mip chain
#: averaged in linear light, trilinear (was: sRGB values filtered as they are, nearest mip
#: level); marker edges, border lines and logos change, uniform regions do not
#: (docs/rendering.md). `eyrc` writes JPEG at quality 95, 4:2:0 (``output.format``,
#: ``output.jpeg_quality``): its images are ``images/NNNNNN.jpg`` and its GT records that
#: path. (b) derived facts of each scene in the GT's ``params`` (``derived.*``: largest box
#: aspect ratio, smallest distance from a box to the frame's edge, touching boxes, smallest
#: gap between boxes; generator/truth/scene_facts.py).
#: 7: `eyrc` seen by the camera that rendered the competition's example (its Gazebo mount:
#: 20 m up, pitch 1.5 rad, horizontal field of view 1.2 rad; generator/fitting/competition_world.py)
#: instead of a 1.047 rad camera fitted to the marker corners: the markers' squares now differ
#: from the example by 0.5 grey levels (was 4.5). The example's boxes are refitted through
#: it (on the world files' grid); other presets do not change.
#: 8: textures sampled at GL's level of detail computed exactly in the fragment shader
#: (lambda = log2 of the larger texel footprint of a pixel step); llvmpipe's implicit lambda
#: was 0.03-0.04 lower. Marker squares of the fitted example 0.47 -> 0.31 grey levels (as
#: JPEG), the warp's top-left corner pixel 184 -> 185 as on the example. Every preset's
#: images change by a grey level or so along texture edges; GT does not change.
GENERATOR_VERSION = "8"

#: A post-render hook: (rgb uint8 (H, W, 3), rng) -> rgb uint8 (H, W, 3).
Degrade = Callable[[np.ndarray, np.random.Generator], np.ndarray]


@dataclass(frozen=True)
class ImageFormat:
    """How an image file is encoded: a preset's ``output.format``, ``output.jpeg_quality`` and
    ``output.jpeg_subsampling``.

    Attributes
    ----------
    image_format : str
        ``png`` or ``jpeg`` (:data:`arenabench.imageio.IMAGE_EXTENSIONS`).
    jpeg_quality : int
        JPEG quality of ``jpeg``.
    jpeg_subsampling : str
        JPEG chroma subsampling of ``jpeg`` (:data:`arenabench.imageio.JPEG_SUBSAMPLINGS`).
    """

    image_format: str = "png"
    jpeg_quality: int = 95
    jpeg_subsampling: str = DEFAULT_JPEG_SUBSAMPLING

    def __post_init__(self) -> None:
        if self.image_format not in IMAGE_EXTENSIONS:
            raise ValueError(f"output.format must be one of {', '.join(IMAGE_EXTENSIONS)}, got "
                             f"{self.image_format!r}")

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> ImageFormat:
        """The ``output.*`` parameters of a resolved preset (:func:`resolve`)."""
        return cls(image_format=str(params["output.format"]),
                   jpeg_quality=int(params["output.jpeg_quality"]),
                   jpeg_subsampling=str(params["output.jpeg_subsampling"]))

    @classmethod
    def of_preset(cls, preset: Any, overrides: dict[str, Value] | None = None) -> ImageFormat:
        """The format of a preset's images (a name, mapping or ResolvedPreset) with
        ``overrides``."""
        return cls.from_params(resolve(preset, overrides))

    @property
    def ext(self) -> str:
        """File extension of the images (``png`` or ``jpg``)."""
        return IMAGE_EXTENSIONS[self.image_format]

    def encode(self, bgr: np.ndarray) -> bytes:
        """The image file's bytes of a BGR image."""
        return encode_image(bgr, image_format=self.image_format,
                            jpeg_quality=self.jpeg_quality,
                            jpeg_subsampling=self.jpeg_subsampling)


@dataclass
class Sample:
    """A rendered scene and its ground truth (``record``; ``gt`` is the GT file's content),
    encoded as ``output`` says (:attr:`image_bytes`)."""

    id: str
    record: GroundTruth
    render: RenderOutput
    timings_ms: dict[str, float] = field(default_factory=dict)
    output: ImageFormat = field(default_factory=ImageFormat)

    @cached_property
    def gt(self) -> dict[str, Any]:
        """The GT file's content: ``record.to_dict()`` (computed once)."""
        return self.record.to_dict()

    @property
    def rgb(self) -> np.ndarray:
        """(H, W, 3) uint8 RGB image (after any degradation)."""
        return self.render.rgb

    @property
    def bgr(self) -> np.ndarray:
        """The image in OpenCV's BGR order."""
        return cv2.cvtColor(self.render.rgb, cv2.COLOR_RGB2BGR)  # 30x faster than numpy

    @cached_property
    def image_bytes(self) -> bytes:
        """The image file's bytes (``output``), encoded once, when first asked for."""
        return self.output.encode(self.bgr)


def worker_renderer() -> Renderer:
    """This thread's reused :class:`~arenabench.generator.rendering.render.Renderer`, created on
    first
    use (:func:`arenabench.workers.thread_state`)."""
    return thread_state("renderer", Renderer)


def worker_gl_info() -> dict[str, str]:
    """OpenGL vendor, renderer and version of :func:`worker_renderer` (asked once)."""
    return thread_state("gl_info", lambda: worker_renderer().gl_info())


def scene_id(index: int) -> str:
    """Zero-padded id of scene ``index`` (``000042``)."""
    return f"{int(index):06d}"


#: Name of the random stream of the post-render degradations (noise).
DEGRADE_STREAM = "degrade"


def degrade_rng(seed: int, index: int) -> np.random.Generator:
    """Random generator for post-render degradations: the scene's stream
    :data:`DEGRADE_STREAM`, independent of every parameter's draws."""
    return stream_rng(seed, index, DEGRADE_STREAM)


def make_sample(
    preset: Any,
    *,
    seed: int,
    index: int,
    overrides: dict[str, Value] | None = None,
    renderer: SceneRenderer | None = None,
    preset_name: str | None = None,
    depth: bool = False,
    masks: bool = False,
    frame: FrameSpec | None = None,
    degrade: Degrade | None = None,
    image_ext: str | None = None,
) -> Sample:
    """Sample scene ``index`` of a run, then make its image and GT (:func:`scene_image`).

    Parameters
    ----------
    preset : str, dict or ResolvedPreset
        Preset name, parameter mapping, or a preset file's
        :class:`~arenabench.generator.parameters.preset_files.ResolvedPreset`.
    seed, index : int, keyword-only
        Run seed and scene index.
    overrides : dict, keyword-only
        Parsed ``--set`` values.
    renderer : SceneRenderer, keyword-only
        Reused renderer; a temporary :class:`~arenabench.generator.rendering.render.Renderer` is
        created (slow) when omitted.
    preset_name : str, keyword-only
        Name recorded in the GT (default: the preset's name; ``custom`` for a mapping).
    depth, masks : bool, keyword-only
        Also render depth / instance masks.
    frame : FrameSpec, keyword-only
        Rectified frame (default 1000 px, inner corners).
    degrade : callable, keyword-only
        Post-render hook ``(rgb, rng) -> rgb``, run after the preset's own ``degrade.*``
        degradations (:func:`arenabench.generator.rendering.degrade.apply_degradations`), with the
        same random generator.
    image_ext : str, keyword-only
        Extension of the image path recorded in the GT (default: the preset's
        ``output.format``'s).

    Returns
    -------
    Sample
        Encoded as the preset's ``output.*`` say (:class:`ImageFormat`).
    """
    t0 = time.perf_counter()
    sampled = sample_scene(preset, seed=seed, index=index, overrides=overrides)
    t1 = time.perf_counter()
    if preset_name is None:  # a name, a ResolvedPreset's name, or "custom" for a mapping
        preset_name = "custom" if isinstance(preset, Mapping) else _name_of(preset)
    sample = scene_image(
        sampled.scene, sid=scene_id(index), preset=preset_name, seed=seed, index=index,
        params=sampled.params, overrides=overrides, renderer=renderer,
        output=ImageFormat.of_preset(preset, overrides), depth=depth, masks=masks,
        frame=frame, degrade=degrade, image_ext=image_ext)
    sample.timings_ms = {"sample": (t1 - t0) * 1e3, **sample.timings_ms}
    return sample


def scene_image(
    scene: Any,
    *,
    sid: str,
    preset: str,
    seed: int,
    index: int,
    params: Mapping[str, Any],
    renderer: SceneRenderer | None = None,
    output: ImageFormat | None = None,
    overrides: dict[str, Value] | None = None,
    depth: bool = False,
    masks: bool = False,
    frame: FrameSpec | None = None,
    degrade: Degrade | None = None,
    image_ext: str | None = None,
) -> Sample:
    """The image recipe: render ``scene``, degrade it, and annotate it (GT), to be encoded as
    ``output`` says (:attr:`Sample.image_bytes`).

    The one function that makes an image of a scene: the dataset writer (through
    :func:`make_sample`) and the phase check (on its moved scenes) both call it.

    Parameters
    ----------
    scene : Scene
        The scene.
    sid : str, keyword-only
        Image id recorded in the GT (``"000042"``).
    preset : str, keyword-only
        Preset name recorded in the GT.
    seed, index : int, keyword-only
        Run seed and scene index: the degradations' random stream (:func:`degrade_rng`).
    params : mapping, keyword-only
        The scene's drawn parameter values: its ``degrade.*`` give the degradations; the GT
        records them rounded (derived facts are computed anew).
    renderer : SceneRenderer, keyword-only
        Reused renderer; a temporary one is created (slow) when omitted.
    output : ImageFormat, keyword-only
        How the image is encoded (default: PNG).
    overrides : dict, keyword-only
        The ``--set`` values recorded in the GT.
    depth, masks, frame, degrade, image_ext : keyword-only
        As :func:`make_sample`'s.

    Returns
    -------
    Sample
    """
    output = output or ImageFormat()
    own = renderer is None
    renderer = renderer or Renderer()
    t1 = time.perf_counter()
    try:
        out = renderer.render(scene, depth=depth, masks=masks)
    finally:
        if own:
            renderer.close()
    degradations = Degradations.from_params(params)
    if degrade is not None or not degradations.is_neutral:
        rng = degrade_rng(seed, index)
        out.rgb = apply_degradations(out.rgb, degradations, rng)
        if degrade is not None:
            out.rgb = np.ascontiguousarray(degrade(out.rgb, rng))
    t2 = time.perf_counter()
    recorded = {k: v for k, v in params.items() if not k.startswith("derived.")}
    record = ground_truth_record(
        scene, sid=sid, preset=preset, seed=seed, index=index, params=rounded(recorded),
        overrides=overrides, frame=frame, image_ext=image_ext or output.ext,
    )
    t3 = time.perf_counter()
    timings = {"render": (t2 - t1) * 1e3, "gt": (t3 - t2) * 1e3}
    return Sample(id=sid, record=record, render=out, timings_ms=timings, output=output)


def gt_record(scene: Any, **options: Any) -> dict[str, Any]:
    """The GT file content (schema ``arenabench.gt/1``) of a scene rendered as image ``sid``:
    :func:`ground_truth_record`'s ``to_dict()`` (same options)."""
    return ground_truth_record(scene, **options).to_dict()


def ground_truth_record(
    scene: Any, *, sid: str, preset: str, seed: int = 0, index: int = 0,
    params: dict[str, Any] | None = None, overrides: dict[str, Value] | None = None,
    frame: FrameSpec | None = None, image_ext: str = "png",
) -> GroundTruth:
    """The ground truth (schema ``arenabench.gt/1``) of a scene rendered as image ``sid``.

    Parameters
    ----------
    scene : Scene
        The rendered scene.
    sid : str, keyword-only
        Image id (``"000042"``).
    preset : str, keyword-only
        Preset name (or the scene file's name) recorded in the GT.
    seed, index : int, keyword-only
        Run seed and scene index (0 for a scene rendered on its own).
    params, overrides : dict, keyword-only
        Sampled parameter values and the ``--set`` overrides; the scene's derived facts
        (:func:`arenabench.generator.truth.scene_facts.derived_facts`) are added to ``params``.
    frame : FrameSpec, keyword-only
        Rectified frame (default 1000 px, inner corners).
    image_ext : str, keyword-only
        Extension of the image path recorded in the GT.

    Returns
    -------
    GroundTruth
    """
    return GroundTruth.from_dict({
        "schema": GT_SCHEMA,
        "id": sid,
        "image": f"images/{sid}.{image_ext}",
        "preset": preset,
        "seed": int(seed),
        "index": int(index),
        "generator_version": GENERATOR_VERSION,
        "params": {**(params or {}), **rounded(derived_facts(scene, frame=frame))},
        "overrides": {k: _jsonable(v) for k, v in sorted((overrides or {}).items())},
        **compute_ground_truth(scene, frame=frame),
    })


def _jsonable(value: Any) -> Any:
    if isinstance(value, Range):
        return [value.lo, value.hi]
    return list(value) if isinstance(value, tuple) else value
