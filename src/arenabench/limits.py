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

#: Largest obstacle count, and number of connected components, of a ground truth and of a
#: pipeline's answer: a scene holds at most :data:`MAX_SCENE_OBJECTS` obstacles, its GT counts
#: those overlapping the frame, and the union of their (convex) silhouettes has at most as many
#: pieces. An answer beyond it is ``bad_output``, a GT beyond it a dataset error; reports bin
#: counts up to it at most.
MAX_COUNT = MAX_SCENE_OBJECTS

#: Largest ArUco marker id of a ground truth and of an answer: the last id of the largest
#: predefined OpenCV dictionary (``DICT_APRILTAG_36h10``, 2320 ids).
MAX_MARKER_ID = 2319

#: Largest area of a ground truth, in frame px: every GT area is clipped to the frame square,
#: whose side is at most :data:`MAX_IMAGE_SIDE_PX` (``frame.size``), so it is at most the side
#: squared; the factor 2 leaves room for ``area.contour_px``, which counts a pixelated outline
#: and may pass the polygon's area by up to a pixel per piece.
MAX_AREA_PX = 2 * MAX_IMAGE_SIDE_PX**2

#: Longest image id of a dataset's manifest (ids name files: ``gt/<id>.json``, and rows of
#: every report); an id is letters, digits, ``.``, ``_`` and ``-``, not starting with ``.``
#: or ``-``.
MAX_IMAGE_ID_CHARS = 128

#: Longest text parameter (``arena.logo_text``, a dictionary's name, a palette ...): a logo is
#: drawn with ``cv2.putText``, whose time and memory grow with the text; text holds printable
#: characters only (no newline, no NUL): :func:`text_problem`.
MAX_TEXT_CHARS = 64

#: Shown of a refused value in a one-line error, at most (a 20 MB value is not echoed).
MAX_SHOWN_CHARS = 80

#: Largest scene file read (``render``, ``fit``'s output; one of :data:`MAX_SCENE_OBJECTS` boxes
#: and as many patches is about half a megabyte).
MAX_SCENE_FILE_BYTES = 8 * 1024**2

#: Largest ``dataset.json`` read (the generator's is a few kilobytes).
MAX_DATASET_META_BYTES = 1024**2

#: Largest preset file read (``--preset FILE``; a complete one is a few kilobytes). A
#: ``dataset.json`` given as a preset is held to :data:`MAX_DATASET_META_BYTES` too.
MAX_PRESET_FILE_BYTES = MAX_DATASET_META_BYTES

#: Largest arena texture image file read (``arena.texture_file``); its sides are at most
#: :data:`MAX_IMAGE_SIDE_PX` too (an 8192 px square RGBA upload is 256 MiB of GPU memory).
MAX_TEXTURE_BYTES = 256 * 1024**2

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
#: :class:`arenabench.eval.runs.limits.RunLimits`).
DEFAULT_TIMEOUT_S = 60.0
DEFAULT_MEMORY_BYTES = 2 * 1024**3
DEFAULT_MAX_PROCS = 64
DEFAULT_MAX_FILE_SIZE = 64 * 1024**2
DEFAULT_MAX_OUTPUT = 1024**2
#: Default of ``--max-disk``: what one run (under bubblewrap) may write in all, in its working
#: folder, ``/tmp`` and ``/dev/shm`` together (a tmpfs of this size: memory, never the machine's
#: disk). A competition script writes ``obstacles.txt`` and a few images of a few MiB.
DEFAULT_MAX_DISK = 256 * 1024**2

#: Longest wall-clock time one external run may be given (``--timeout``, seconds): a day.
MAX_TIMEOUT_S = 86400.0
#: Shortest ``--timeout`` (seconds). A run starts a process (or a sandbox), copies the image
#: and the pipeline decodes it: starting Python and importing numpy and OpenCV alone takes a
#: few hundred ms, more on a busy machine. Below a second every image of a script would time
#: out whatever it does (``1e-320`` was once accepted and timed out everything).
MIN_TIMEOUT_S = 1.0

#: Largest byte size of a run limit (``--memory-limit``, ``--max-file-size``,
#: ``--max-output``): 1 PiB, well inside ``rlim_t``.
MAX_RUN_BYTES = 1024**5

#: Most processes one external run may be allowed at once (``--max-procs``).
MAX_RUN_PROCS = 65536
#: Largest folder copied into every run's working directory (``RunSettings.workdir_from``:
#: ``arenabench check`` copies the script's folder), in bytes and in files.
MAX_WORKDIR_COPY_BYTES = 64 * 1024**2
MAX_WORKDIR_COPY_FILES = 2000

#: Images an external run leaves in its working directory (its warp, ...) that the HTML
#: report shows on the image's failure card (:mod:`arenabench.eval.runs.run_images`): most
#: directory entries looked at, most images kept per run, largest file read (bytes), largest
#: image decoded (px, from its header), longest side of the thumbnail kept (px).
MAX_RUN_IMAGE_ENTRIES = 256
MAX_RUN_IMAGES = 3
MAX_RUN_IMAGE_BYTES = 16 * 1024**2
MAX_RUN_IMAGE_PIXELS = 2**23
RUN_IMAGE_THUMB_PX = 250

#: Most SSIM refinement rounds of ``fit`` (``--refine-rounds``).
MAX_REFINE_ROUNDS = 100

#: Longest time one step of making the competition's Python environment may take (``python -m
#: venv``, ``pip install`` of its numpy and OpenCV: about 80 MB from the package index), seconds.
COMPETITION_ENV_BUILD_TIMEOUT_S = 1200.0


def text_problem(text: str) -> str | None:
    """Why ``text`` cannot be a text parameter (too long, or a character that is not
    printable), or ``None``."""
    if len(text) > MAX_TEXT_CHARS:
        return f"{len(text)} characters: text holds at most {MAX_TEXT_CHARS}"
    if not text.isprintable():
        bad = next(c for c in text if not c.isprintable())
        return f"holds {bad!r}: text holds printable characters only"
    return None


def cut(text: str) -> str:
    """``text`` cut to :data:`MAX_SHOWN_CHARS` (an error line names a value, never megabytes
    of it)."""
    if len(text) <= MAX_SHOWN_CHARS:
        return text
    return f"{text[:MAX_SHOWN_CHARS - 20]}... ({len(text)} characters)"


def shown(value: object) -> str:
    """``repr(value)`` as an error line shows it (:func:`cut`)."""
    return cut(repr(value))
