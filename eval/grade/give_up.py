"""Giving up on a team after a run of consecutive timeouts (``grade --give-up-after N``).

A submission that hangs costs ``--timeout`` seconds on every image (a team that sleeps forever
on 200 images, 60 s and 2 workers: 100 minutes). The rule, with ``N`` = ``--give-up-after``:

- a team's images run in image order (its units are queued in that order and the workers take
  them first come, first served);
- as the team's results come back, grade looks for ``N`` images in a row, in image order, whose
  runs have all come back as ``timeout``: the order in which results come back (which depends
  on the workers) does not matter, only which images timed out;
- once it finds such a run (images ``a`` to ``b``), it gives up on the team: every image after
  ``b`` whose result is not back is not run (or, when running, stopped) and recorded as a
  ``timeout`` with the message ``not run: K consecutive timeouts before it (a to b)``; results
  that came back before stand, and so do the images before ``a`` still running.

``N = 0`` never gives up. The skipped images count as timeouts in every figure; the team's
``report.json`` and ``grade-state.json`` say how many were not run (``given_up``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from arenabench.eval.scoring.results import Prediction


@dataclass(frozen=True)
class GiveUp:
    """Why and where grade gave up on a team.

    Parameters
    ----------
    after : int
        ``--give-up-after``.
    first, last : str
        Ids of the first and last image of the run of timeouts.
    timeouts : int
        Images in the run (at least ``after``).
    not_run : int
        Images recorded as timeouts without (a whole) run.
    """

    after: int
    first: str
    last: str
    timeouts: int
    not_run: int

    @property
    def message(self) -> str:
        """The message of every image not run."""
        return (f"not run: {self.timeouts} consecutive timeouts before it ({self.first} to "
                f"{self.last}); grade gave up on this team (--give-up-after {self.after})")

    def prediction(self) -> Prediction:
        """What an image not run is recorded as."""
        return Prediction(status="timeout", message=self.message)

    def to_dict(self) -> dict[str, Any]:
        """JSON form (``given_up`` of the team's ``report.json`` and ``grade-state.json``)."""
        return {"after": self.after, "first": self.first, "last": self.last,
                "timeouts": self.timeouts, "not_run": self.not_run}

    def text(self) -> str:
        """One line for grade's output."""
        return (f"gave up after {self.timeouts} consecutive timeouts ({self.first} to "
                f"{self.last}): {self.not_run} images not run")


def _timed_out(pred: Prediction | None) -> bool:
    return pred is not None and pred.status == "timeout"


def timeout_run(preds: Sequence[Prediction | None], index: int) -> tuple[int, int] | None:
    """The run of images, in image order, around ``index`` whose results are back and timed
    out: ``(first, last)`` indices (``None`` when image ``index`` did not time out)."""
    if not _timed_out(preds[index]):
        return None
    first = last = index
    while first > 0 and _timed_out(preds[first - 1]):
        first -= 1
    while last + 1 < len(preds) and _timed_out(preds[last + 1]):
        last += 1
    return first, last


def first_timeout_run(preds: Sequence[Prediction | None], after: int) -> tuple[int, int] | None:
    """The first run, in image order, of at least ``after`` timeouts among ``preds`` (``None``:
    none, or ``after`` is 0)."""
    if after < 1:
        return None
    index = 0
    while index < len(preds):
        run = timeout_run(preds, index)
        if run is None:
            index += 1
            continue
        if run[1] - run[0] + 1 >= after:
            return run
        index = run[1] + 1
    return None
