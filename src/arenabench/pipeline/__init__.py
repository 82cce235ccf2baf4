"""The reference detection pipeline: markers -> homography -> obstacle count and area.

Public API::

    from arenabench.pipeline import DetectConfig, detect
    result = detect(image_bgr, DetectConfig(profile="reference"))
    result.count, result.total_area, result.to_json()

``detect`` is a pure function (no file I/O); :mod:`arenabench.imageio` loads images and
:mod:`arenabench.detect` is the competition-compatible command.
"""

from arenabench.pipeline.config import (
    ALL_DICTIONARIES,
    PROFILES,
    PUBLISHED_DICTIONARIES,
    DetectConfig,
)
from arenabench.pipeline.detection import detect
from arenabench.pipeline.result import DETECTION_SCHEMA, Detection, Obstacle

__all__ = [
    "ALL_DICTIONARIES",
    "DETECTION_SCHEMA",
    "PROFILES",
    "PUBLISHED_DICTIONARIES",
    "DetectConfig",
    "Detection",
    "Obstacle",
    "detect",
]
