"""Giving up on a team after a run of consecutive timeouts (``grade --give-up-after N``).

A submission that hangs costs ``--timeout`` seconds on every image (a team that sleeps forever
on 200 images, 60 s and 2 workers: 100 minutes). The rule, with ``N`` = ``--give-up-after``:

- a team's images run in image order (its units are queued in that order and the workers take
  them first come, first served);
- as the team's results come back, grade looks for ``N`` images in a row, in image order, whose
  runs have all come back as ``timeout``. Once it finds such a run, it runs none of the team's
  images after it: a queued one never starts, a running one is stopped. This is only a saving
  of time; it does not decide the verdicts;
- the verdicts are settled when the team's last result is in (:func:`settle`): the first ``N``
  timeouts in a row in image order (images ``a`` to ``b``) decide, and **every** image after
  ``b`` is recorded as a ``timeout`` with the message ``skipped: N consecutive timeouts before
  it (a to b)``, whether it ran or not. Images up to ``b`` keep their own results (those still
  running when grade gave up end within their own timeout).

So how many workers ran at once, and the order their results came back in, changes how much
time a hanging team costs but never its verdicts: with 4 workers, images 0 to 3 of a team
that hangs all run and all time out; with 1 worker, image 3 never starts; both record images
0 to 2 as timeouts and image 3 onwards as skipped. ``N = 0`` never gives up. The skipped images
count as timeouts in every figure; the team's ``report.json`` and ``grade-state.json`` say how
many were skipped (``given_up``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from arenabench.eval.scoring.results import Prediction
from arenabench.records import to_plain


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
    skipped : int
        Images after the run, recorded as timeouts whether they ran or not.
    """

    after: int
    first: str
    last: str
    timeouts: int
    skipped: int

    @property
    def message(self) -> str:
        """The message of every image skipped."""
        return (f"skipped: {self.timeouts} consecutive timeouts before it ({self.first} to "
                f"{self.last}); grade gave up on this team (--give-up-after {self.after})")

    def prediction(self) -> Prediction:
        """What an image skipped is recorded as."""
        return Prediction(status="timeout", message=self.message)

    def to_dict(self) -> dict[str, Any]:
        """JSON form (``given_up`` of the team's ``report.json`` and ``grade-state.json``)."""
        return to_plain(self)

    def text(self) -> str:
        """One line for grade's output."""
        return (f"gave up after {self.timeouts} consecutive timeouts ({self.first} to "
                f"{self.last}): {self.skipped} later images skipped")


def _timed_out(pred: Prediction | None) -> bool:
    """A team's own timeout (a starved run is the machine's: never one of them)."""
    return pred is not None and pred.status == "timeout" and not pred.starved


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


def settle(preds: list[Prediction | None], after: int,
           ids: Sequence[str]) -> GiveUp | None:
    """Settle a team's verdicts once its last result is in: the first ``after`` timeouts in a
    row, in image order, decide, and every image after them is recorded as skipped (in
    ``preds``, in place), whether it ran or not.

    Parameters
    ----------
    preds : list of Prediction or None
        The team's predictions in image order. ``None`` (not run) may only follow a run of
        ``after`` timeouts: every image up to the end of the first such run must hold its own
        result, which is what grade guarantees (it stops running a team only after such a run).
    after : int
        ``--give-up-after`` (0: never).
    ids : sequence of str
        The images' ids, in the same order.

    Returns
    -------
    GiveUp or None
        Where grade gave up (``None``: it did not).

    Raises
    ------
    ValueError
        When an image has no result and no run of ``after`` timeouts comes before it.
    """
    end = None
    if after >= 1:
        row = 0
        for j, pred in enumerate(preds):
            row = row + 1 if _timed_out(pred) else 0
            if pred is None:
                break
            if row >= after:
                end = j
                break
    if end is None:
        missing = [ids[j] for j, p in enumerate(preds) if p is None]
        if missing:
            raise ValueError(f"preds: image {missing[0]} has no result and no run of {after} "
                             "timeouts comes before it")
        return None
    given_up = GiveUp(after=after, first=ids[end - after + 1], last=ids[end], timeouts=after,
                      skipped=len(preds) - end - 1)
    skip = given_up.prediction()
    for j in range(end + 1, len(preds)):
        preds[j] = skip
    return given_up
