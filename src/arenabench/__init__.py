"""arenabench: test overhead ArUco-arena obstacle-detection pipelines.

Three import packages share this distribution:

- ``arenabench`` (this one): the reference detection pipeline, the shared data model
  (rectified frame, competition I/O, file helpers) and the command-line interface.
- ``arenabench.generator``: scene model, sampling, off-screen rendering, analytic ground truth.
- ``arenabench.eval``: pipeline adapters, metrics, reports and sweeps.

The pipeline never imports the generator; the generator never imports the harness.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("arenabench")
except PackageNotFoundError:  # pragma: no cover - running from a source tree without install
    __version__ = "0.0.0+unknown"

__all__ = ["__version__"]
