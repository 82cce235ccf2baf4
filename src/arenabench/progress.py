"""The one progress rule of every command (generate, eval, sweep, contact-sheet, bench, ...).

On a terminal (stderr is a TTY) a tqdm bar; otherwise (logs, CI, pipes) a few plain lines on
stderr, one each time another 10 % is done (at most one per 2 s) or 10 s have passed, and
one at the end; nothing at all when disabled (``--no-progress``). Use :func:`progress` as a
context manager::

    with progress(len(tasks), desc="generate", unit="img", enabled=show) as bar:
        for task in tasks:
            ...
            bar.update(1)
"""

from __future__ import annotations

import sys
import threading
import time
from collections import deque
from typing import Any, TextIO

#: Plain-line mode: a line each time this fraction of the work is done ...
PLAIN_STEP_FRACTION = 0.10
#: ... or this many seconds have passed since the last line ...
PLAIN_STEP_SECONDS = 10.0
#: ... but never sooner than this after the last line (a short run prints little).
PLAIN_MIN_SECONDS = 2.0
#: No estimate of the time left before this share of the work is done (one slow first unit
#: says nothing of the rest: a hanging team's first timeouts once made "eta 53 h").
ETA_MIN_FRACTION = 0.05
#: The estimate uses the pace of the last this many seconds (work that got faster or slower,
#: a team given up on, shows within it); the whole run while it is shorter.
ETA_WINDOW_S = 120.0


class _Closing:
    def __enter__(self) -> Any:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:  # pragma: no cover - overridden
        pass


class _Silent(_Closing):
    def update(self, n: int = 1) -> None:
        pass

    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None:
        pass

    def close(self) -> None:
        pass


class PlainProgress(_Closing):
    """Progress as plain lines (``desc: 40/100 img (40 %), 12.3 s, eta 18 s; status``) for
    non-terminal stderr.

    The estimate of the time left is the units left at the pace of the last
    :data:`ETA_WINDOW_S` seconds, given once :data:`ETA_MIN_FRACTION` of the work is done;
    ``status`` is the last :meth:`set_postfix_str` (tqdm's name). With ``heartbeat`` a line is
    also printed every :data:`PLAIN_STEP_SECONDS` while nothing finishes (a hanging run, a
    long first unit), so a log never stays silent for minutes.

    Parameters
    ----------
    total : int
        Units of work.
    desc, unit : str, keyword-only
        What is counted (``"generate"``, ``"img"``).
    file : text stream, keyword-only
        Where lines go (default ``sys.stderr``).
    clock : callable, keyword-only
        Seconds now (default :func:`time.monotonic`).
    heartbeat : bool, keyword-only
        Print a line every :data:`PLAIN_STEP_SECONDS` even when no unit finishes (a thread
        of its own; :func:`progress` turns it on).
    """

    def __init__(self, total: int, *, desc: str, unit: str, file: TextIO | None = None,
                 clock: Any = time.monotonic, heartbeat: bool = False) -> None:
        self.total, self.desc, self.unit = max(0, int(total)), desc, unit
        self.file = file if file is not None else sys.stderr
        self.clock = clock
        self.n = 0
        self._start = self._last_time = clock()
        self._last_n = 0
        self._closed = False
        self._lock = threading.Lock()
        self._pace: deque[tuple[float, int]] = deque([(self._start, 0)])
        self.status = ""
        self._stop = threading.Event()
        if heartbeat:
            threading.Thread(target=self._beat, name="arenabench-progress", daemon=True).start()

    def set_postfix_str(self, s: str = "", refresh: bool = True) -> None:
        """What the next lines add after the counts (say, the teams under way)."""
        self.status = str(s)

    def drop(self, n: int) -> None:
        """Take ``n`` units out of the work (they will not be done: a team given up on)."""
        with self._lock:
            self.total = max(self.n, self.total - int(n))

    def eta(self) -> float | None:
        """Seconds left at the recent pace; ``None`` until it means something."""
        if not ETA_MIN_FRACTION * self.total <= self.n < self.total or self.n <= 0:
            return None
        now = self.clock()
        while len(self._pace) > 1 and self._pace[1][0] <= now - ETA_WINDOW_S:
            self._pace.popleft()  # the newest point at or before the window's start stays
        t0, n0 = self._pace[0]
        t0 = max(t0, now - ETA_WINDOW_S)  # the count at the window's start was n0
        if self.n <= n0 or now <= t0:
            return None
        return (now - t0) * (self.total - self.n) / (self.n - n0)

    def _line(self, *, final: bool = False) -> None:
        pct = f" ({100 * self.n / self.total:.0f} %)" if self.total else ""
        seconds = self.clock() - self._start
        left = None if final else self.eta()
        eta = "" if left is None else f", eta {duration_text(left)}"
        status = f"; {self.status}" if self.status and not final else ""
        print(f"{self.desc}: {self.n}/{self.total} {self.unit}{pct}, {seconds:.1f} s{eta}"
              f"{status}", file=self.file, flush=True)
        self._last_n, self._last_time = self.n, self.clock()

    def update(self, n: int = 1) -> None:
        """Count ``n`` more units; print a line when a step is reached."""
        with self._lock:
            self.n += n
            self._pace.append((self.clock(), self.n))
            step = max(1, round(self.total * PLAIN_STEP_FRACTION))
            if self.n >= self.total or self._closed:
                return  # the final line comes from close()
            since = self.clock() - self._last_time
            if since >= PLAIN_STEP_SECONDS or (
                self.n - self._last_n >= step and since >= PLAIN_MIN_SECONDS
            ):
                self._line()

    def tick(self) -> None:
        """Print a line when :data:`PLAIN_STEP_SECONDS` have passed since the last one (the
        heartbeat calls it; nothing finished meanwhile)."""
        with self._lock:
            if not self._closed and self.clock() - self._last_time >= PLAIN_STEP_SECONDS:
                self._line()

    def _beat(self) -> None:
        while not self._stop.wait(1.0):
            try:
                self.tick()
            except (OSError, ValueError):  # the stream is closed: nothing more to say
                return

    def close(self) -> None:
        """Print the final line (once)."""
        self._stop.set()
        with self._lock:
            if not self._closed:
                self._closed = True
                self._line(final=True)


def drop(bar: Any, n: int) -> None:
    """Take ``n`` units out of the work of ``bar`` (what :func:`progress` returned)."""
    if isinstance(bar, PlainProgress):
        bar.drop(n)
    elif getattr(bar, "total", None) is not None:  # tqdm
        bar.total = max(bar.n, bar.total - int(n))
        bar.refresh()


def duration_text(seconds: float) -> str:
    """``"12 s"``, ``"9 min 10 s"``, ``"2 h 05 min"``."""
    s = max(0, round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def progress(total: int, *, desc: str, unit: str = "img", enabled: bool = True,
             file: TextIO | None = None) -> Any:
    """A progress object with ``update(n)`` and ``close()``, usable in ``with``: a tqdm bar,
    plain lines or nothing.

    Parameters
    ----------
    total : int
        Units of work.
    desc : str, keyword-only
        Label (the command's name, e.g. ``"eval reference"``).
    unit : str, keyword-only
        Unit counted (default ``"img"``).
    enabled : bool, keyword-only
        False: no output at all.
    file : text stream, keyword-only
        Default ``sys.stderr``; the bar is drawn only when it is a terminal.

    Returns
    -------
    tqdm.tqdm or PlainProgress or a silent stand-in
    """
    stream = file if file is not None else sys.stderr
    if not enabled or total <= 0:
        return _Silent()
    if _isatty(stream):
        from tqdm import tqdm

        return tqdm(total=total, desc=desc[:40], unit=unit, file=stream, dynamic_ncols=True)
    return PlainProgress(total, desc=desc, unit=unit, file=stream, heartbeat=True)


def _isatty(stream: TextIO) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False
