"""The renderer interface: a :class:`~arenabench.generator.model.scene.Scene` in, pixels out.

The scene is plain data (:mod:`arenabench.generator.model.scene`); a renderer is an adapter behind
:class:`SceneRenderer` that turns it into a :class:`RenderOutput`. Callers (the sample
builder, the dataset writer, sweeps, the bench) depend on this interface only; the
adapters are :class:`arenabench.generator.rendering.render.Renderer` (the generator's pyrender
renderer)
and :class:`arenabench.generator.rendering.render.NaiveRenderer` (the bench's baseline). Everything
a
pyrender adapter needs from pyrender's private API is in
:mod:`arenabench.generator.rendering.pyrender_compat`.

This module imports neither pyrender nor OpenGL.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeVar

import numpy as np

if TYPE_CHECKING:
    from arenabench.generator.model.scene import Scene

_R = TypeVar("_R", bound="SceneRenderer")


@dataclass
class RenderOutput:
    """What one render gives back.

    Attributes
    ----------
    rgb : numpy.ndarray
        (H, W, 3) uint8, RGB order.
    depth : numpy.ndarray or None
        (H, W) float32 distance along the optical axis in metres, 0 where nothing was hit.
    instance_mask : numpy.ndarray or None
        (H, W) uint8: 0 for no obstacle, ``i + 1`` where obstacle ``i`` is the nearest surface.
    """

    rgb: np.ndarray
    depth: np.ndarray | None = None
    instance_mask: np.ndarray | None = None


class SceneRenderer(abc.ABC):
    """A renderer of scenes: :meth:`render`, :meth:`gl_info`, :meth:`close`; a context manager.

    Examples
    --------
    >>> with Renderer() as r:                       # doctest: +SKIP
    ...     out = r.render(scene, masks=True)
    """

    @abc.abstractmethod
    def render(self, scene: Scene, *, depth: bool = False, masks: bool = False) -> RenderOutput:
        """Render ``scene``.

        Parameters
        ----------
        scene : Scene
            What to draw (its camera gives the image size).
        depth : bool, keyword-only
            Also return the depth map.
        masks : bool, keyword-only
            Also return the per-obstacle instance mask.

        Returns
        -------
        RenderOutput
        """

    @abc.abstractmethod
    def gl_info(self) -> dict[str, str]:
        """What draws the pixels: ``gl_renderer``, ``gl_version`` and ``gl_platform`` strings."""

    @abc.abstractmethod
    def close(self) -> None:
        """Release the renderer's resources (idempotent)."""

    def __enter__(self: _R) -> _R:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
