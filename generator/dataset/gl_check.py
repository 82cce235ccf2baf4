"""Is off-screen OpenGL usable here? Asked by every command that renders, before it creates
any file, so a broken OpenGL setup is one line pointing at ``arenabench doctor`` instead of a
traceback from every worker and a half-made output folder.
"""

from __future__ import annotations

#: What a command tells its user when OpenGL does not work.
DOCTOR_HINT = "run 'arenabench doctor' to see what is missing and how to install it"


class OffscreenGLError(RuntimeError):
    """No usable off-screen OpenGL context; the message is one line ending in
    :data:`DOCTOR_HINT`."""


def require_offscreen_gl() -> dict[str, str]:
    """Create this thread's renderer (:func:`arenabench.generator.dataset.make.worker_renderer`,
    which the command's in-process renders then reuse) and return its OpenGL strings.

    Returns
    -------
    dict
        ``gl_renderer``, ``gl_version``, ``gl_platform``.

    Raises
    ------
    OffscreenGLError
        When the OpenGL platform's libraries are missing or no context can be created.
    """
    from arenabench.doctor import check_gl_platform

    check, _ = check_gl_platform()
    if not check.ok:
        raise OffscreenGLError(f"no off-screen OpenGL: {_one_line(check.detail)}; {DOCTOR_HINT}")
    from arenabench.generator.dataset.make import worker_gl_info

    try:
        return worker_gl_info()
    except Exception as exc:  # ImportError, GLError, EGL errors, RuntimeError: all one cause
        why = " ".join(str(a) for a in exc.args if a) or type(exc).__name__
        raise OffscreenGLError(f"cannot create an off-screen OpenGL context "
                               f"({_one_line(why)}); {DOCTOR_HINT}") from None


def _one_line(text: str, limit: int = 200) -> str:
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 3] + "..."
