"""The project's reference pipeline as a plain callable (for ``--pipeline
reference_callable:detect``)."""

from arenabench.pipeline import DetectConfig
from arenabench.pipeline import detect as _detect

_CONFIG = DetectConfig(profile="reference")


def detect(image):
    """Run the reference profile on a BGR image; returns the Detection object."""
    return _detect(image, _CONFIG)
