"""Largest sizes arenabench accepts, declared once.

A request beyond one of these is refused up front with a one-line error naming the limit,
instead of allocating (or looping) until memory or the GL driver gives out.
"""

from __future__ import annotations

#: Largest image side in px: camera width/height of a scene, the rectified frame
#: (``detect --frame-size``), contact-sheet tiles and the whole sheet. Off-screen GL
#: renderbuffers are commonly limited to 8192 or 16384 px; a 8192 x 8192 BGR image is 192 MiB.
MAX_IMAGE_SIDE_PX = 8192

#: Most obstacles, and most floor patches, in one scene (a scene file's ``obstacles`` and
#: ``patches``): the renderer and the ground truth grow with their number (and with its square
#: for the visibility of every box against every other).
MAX_SCENE_OBJECTS = 1000

#: Largest magnitude of any number in a scene (metres, degrees, pixels, intrinsics): beyond
#: it the camera and geometry arithmetic loses all precision (``inf`` and ``nan`` never pass).
MAX_SCENE_NUMBER = 1e6

#: Most scenes in one dataset (``generate --count``): scene ids have six digits.
MAX_DATASET_SCENES = 1_000_000

#: Most local worker processes or threads (``--workers``) of generate, sweep and eval.
MAX_WORKERS = 256

#: Timeouts in a row (in image order) after which ``grade`` runs none of a team's later images
#: (``--give-up-after``; 0: never): a submission that hangs would otherwise cost ``--timeout``
#: on every image.
DEFAULT_GIVE_UP_AFTER = 3

#: Most scenes rendered by one sweep: points x scenes per point (``sweep --per-point``,
#: ``--random`` and the grid of ``--vary`` axes).
MAX_SWEEP_SCENES = 1_000_000


def check_at_most(value: int, limit: int, what: str) -> None:
    """Raise ``ValueError("<what> = <value> exceeds the limit of <limit>")`` when
    ``value > limit``.

    Parameters
    ----------
    value : int
        The requested size.
    limit : int
        One of this module's maxima.
    what : str
        Names the option or parameter (``"--count"``, ``"camera.width"``).
    """
    if value > limit:
        raise ValueError(f"{what} = {value} exceeds the limit of {limit}")

#: Defaults of an external run's limits (``eval``/``sweep``/``grade`` ``--timeout``,
#: ``--memory-limit``, ``--max-procs``, ``--max-file-size``, ``--max-output``; the fields of
#: :class:`arenabench.eval.run_limits.RunLimits`).
DEFAULT_TIMEOUT_S = 60.0
DEFAULT_MEMORY_BYTES = 2 * 1024**3
DEFAULT_MAX_PROCS = 64
DEFAULT_MAX_FILE_SIZE = 64 * 1024**2
DEFAULT_MAX_OUTPUT = 1024**2

#: Longest wall-clock time one external run may be given (``--timeout``, seconds): a day.
MAX_TIMEOUT_S = 86400.0

#: Largest byte size of a run limit (``--memory-limit``, ``--max-file-size``,
#: ``--max-output``): 1 PiB, well inside ``rlim_t``.
MAX_RUN_BYTES = 1024**5

#: Most processes one external run may be allowed at once (``--max-procs``).
MAX_RUN_PROCS = 65536
#: Largest folder copied into every run's working directory (``RunSettings.workdir_from``:
#: ``arenabench check`` copies the script's folder), in bytes and in files.
MAX_WORKDIR_COPY_BYTES = 64 * 1024**2
MAX_WORKDIR_COPY_FILES = 2000

#: Most SSIM refinement rounds of ``fit`` (``--refine-rounds``).
MAX_REFINE_ROUNDS = 100
