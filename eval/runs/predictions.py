"""What one finished external run (its launcher's result, stdout, stderr and working
directory) comes to, as a :class:`~arenabench.eval.scoring.results.Prediction`
(:func:`prediction_from_run`, cold and warm runs alike), with thumbnails of the images the run
left in its working directory (:mod:`arenabench.eval.runs.run_images`). The answer itself is
read by :mod:`arenabench.eval.scoring.answers`.

Outcome of an external run (:func:`prediction_from_run`)
--------------------------------------------------------
``timeout`` (message ``timed out after T s ...``); ``limit`` when the run failed after
hitting a limit, the message starting with which: ``memory limit (--memory-limit 2G) ...``,
``process limit (--max-procs 64) ...``, ``file size limit (--max-file-size 64M) ...``;
``crash`` (non-zero exit other than :data:`~arenabench.competition.EXIT_MARKERS_NOT_FOUND`,
or a signal); ``markers_not_found`` (that exit status); ``bad_output`` (no or unparseable
``obstacles.txt``, one larger than :data:`OBSTACLES_MAX_BYTES` or not a regular file, no
JSON line); else ``ok``.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any

from arenabench.cliopts import format_size
from arenabench.competition import (
    EXIT_MARKERS_NOT_FOUND,
    OBSTACLES_FILE,
    OutputFormatError,
    parse_obstacles_txt,
)
from arenabench.eval.scoring.answers import last_json_line, prediction_from_result
from arenabench.eval.scoring.results import HarnessError, Prediction, tail

from .limits import RunLimits
from .outputs import read_small
from .proctools import RunRecord
from .run_images import collect_run_images

#: A timed-out run that waited for a CPU (runnable, not running) for at least this share of
#: its timeout was *starved*: the machine, not the pipeline, made it late. Measured from the
#: scheduler's own account of the run's threads (``/proc/PID/task/TID/schedstat``). Not
#: starved: a run whose own threads wanting a CPU outnumber the CPUs it may use (they wait
#: for each other), and one that chose a nice value or policy that puts it behind everything
#: else.
STARVED_SHARE = 0.25
#: Times a starved run is run again; when it starves each time, the harness has failed
#: (:class:`~arenabench.eval.scoring.results.HarnessError`: nothing of the image is scored, and
#: the command says so): a busy machine never makes a team's timeout.
STARVED_RETRIES = 2

#: How a command answers: ``obstacles.txt`` in its working directory, or a JSON line on stdout.
OUTPUT_MODES: tuple[str, ...] = ("obstacles", "json")
#: Largest ``obstacles.txt`` read; a larger one is ``bad_output``.
OBSTACLES_MAX_BYTES = 64 * 1024

_MEMORY_SIGNS = ("MemoryError", "std::bad_alloc", "Cannot allocate memory", "out of memory",
                 "Out of memory", "failed to map segment", "cannot allocate")
_FSIZE_SIGNS = ("File too large",)
_NPROC_SIGNS = ("Resource temporarily unavailable", "BlockingIOError", "fork: retry")




def limit_hit(result: RunRecord, stderr: str, *, limits: RunLimits,
              pids_cgroup: bool) -> str | None:
    """Which limit a failed run hit, as the message's start (``None``: none).

    ``pids_cgroup``: whether the run had a pids cgroup (without one, the process limit is
    ``RLIMIT_NPROC`` and shows only in what the command printed).
    """
    rc, last = result.rc, stderr[-4000:]
    if result.pids_limit_hit or (
        not pids_cgroup and limits.max_procs and any(s in last for s in _NPROC_SIGNS)
    ):
        return f"process limit (--max-procs {limits.max_procs}) reached"
    if rc in (-signal.SIGXFSZ, 128 + signal.SIGXFSZ) or any(s in last for s in _FSIZE_SIGNS):
        return f"file size limit (--max-file-size {format_size(limits.max_file_size)}) reached"
    if any(s in last for s in _MEMORY_SIGNS):
        return f"memory limit (--memory-limit {format_size(limits.memory_bytes)}) reached"
    return None


def prediction_from_run(result: RunRecord, stdout: str, stderr: str, workdir: str, *,
                        output: str, limits: RunLimits, pids_cgroup: bool) -> Prediction:
    """The :class:`Prediction` of one finished external run (see the module docstring).

    Parameters
    ----------
    result : RunRecord
        What the launcher (or the warm server's run manager) recorded of the run.
    stdout, stderr : str
        What the command printed (the kept tails).
    workdir : str
        The run's working directory (where ``obstacles.txt`` is read, and the images the run
        left there: :func:`~arenabench.eval.runs.run_images.collect_run_images`).
    output : {"obstacles", "json"}, keyword-only
        How the command answers (:data:`OUTPUT_MODES`).
    limits : RunLimits, keyword-only
        The run's limits (named in ``limit`` and ``timeout`` messages).
    pids_cgroup : bool, keyword-only
        Whether the run had a pids cgroup (:func:`limit_hit`).

    Raises
    ------
    HarnessError
        When the launcher could not prepare the run (``harness_error``): not the command's
        failure.
    """
    if result.harness_error:
        raise HarnessError(result.harness_error[:500])
    rc, latency = result.rc, float(result.latency_ms)
    keep = {"stdout": tail(stdout), "stderr": tail(stderr), "latency_ms": latency,
            "run_images": collect_run_images(workdir)}
    if result.error:
        return Prediction(status="crash", message=result.error[:500], **keep)
    failed = result.timed_out or rc not in (0, EXIT_MARKERS_NOT_FOUND)
    which = limit_hit(result, stderr, limits=limits, pids_cgroup=pids_cgroup)
    last = stderr.strip().splitlines()[-1:] or [""]
    if which and (failed or result.pids_limit_hit):
        return Prediction(status="limit", message=f"{which}: {last[0][:300]}".rstrip(": "),
                          **keep)
    if result.timed_out:
        msg = f"timed out after {limits.timeout_s:g} s (all its processes killed)"
        wait_s = result.wait_ms / 1e3
        own_crowd = result.runnable > (result.cpus or 1)
        if (wait_s >= STARVED_SHARE * limits.timeout_s and not own_crowd
                and not result.lowered_priority):
            return Prediction(status="timeout", starved=True, message=(
                f"{msg}; starved: it waited {wait_s:.1f} s for a CPU (the machine was busy)"),
                **keep)
        return Prediction(status="timeout", message=msg, **keep)
    if rc not in (0, EXIT_MARKERS_NOT_FOUND):
        why = f"killed by signal {-rc}" if rc < 0 else f"exit status {rc}"
        return Prediction(
            status="crash", message=f"{why}: {last[0][:300]}".rstrip(": "), **keep
        )
    try:
        if output == "json":
            parsed_json: Any = last_json_line(stdout)
            if rc == EXIT_MARKERS_NOT_FOUND and isinstance(parsed_json, dict):
                parsed_json.setdefault("status", "markers_not_found")
            pred = prediction_from_result(parsed_json, latency_ms=latency, stdout=stdout)
            return Prediction(**{**pred.__dict__, "stderr": tail(stderr),
                                 "run_images": keep["run_images"]})
        path = Path(workdir) / OBSTACLES_FILE
        if not os.path.lexists(path):
            if rc == EXIT_MARKERS_NOT_FOUND:
                return Prediction(status="markers_not_found",
                                  message=f"exit status {EXIT_MARKERS_NOT_FOUND}", **keep)
            return Prediction(
                status="bad_output",
                message=f"{OBSTACLES_FILE} was not written to the working directory",
                **keep,
            )
        text = read_small(path, OBSTACLES_MAX_BYTES).decode("utf-8", errors="replace")
        parsed = parse_obstacles_txt(text)
    except OutputFormatError as exc:
        if rc == EXIT_MARKERS_NOT_FOUND:
            return Prediction(status="markers_not_found", message=str(exc), **keep)
        return Prediction(status="bad_output", message=str(exc)[:500], **keep)
    return Prediction(
        status="markers_not_found" if rc == EXIT_MARKERS_NOT_FOUND else "ok",
        count=parsed.count,
        area=parsed.area,
        marker_ids=tuple(parsed.marker_ids),
        message=(f"exit status {EXIT_MARKERS_NOT_FOUND}: markers not found"
                 if rc == EXIT_MARKERS_NOT_FOUND else ""),
        **keep,
    )
