"""Run independent work units on an existing Dask cluster (``--scheduler tcp://HOST:PORT``).

One helper for every command that scales out (``generate``, ``sweep``, ``grade``): the units
are submitted at once, results come back in completion order, each result is dropped from the
cluster as soon as it has been handed over (so large results, such as rendered images, do not
pile up in the workers' memory), and whatever is still pending is cancelled when the caller
stops early (an error, an interrupt, a ``break``). ``dask.distributed`` is imported only when
this runs; :func:`connect` lets a command reach the scheduler before it writes anything.
See ``docs/scale-out.md`` for starting a scheduler and workers.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from typing import Any

from arenabench.interrupts import checkpoint


def connect(scheduler: Any) -> Any:
    """A ``distributed.Client`` of ``scheduler``.

    Parameters
    ----------
    scheduler : str or distributed.Client
        ``tcp://HOST:PORT`` (a new connection, which the caller closes) or a connected client
        (returned as is).

    Raises
    ------
    OSError
        When the scheduler cannot be reached (after ``distributed.comm.timeouts.connect``).
    """
    from distributed import Client

    return scheduler if isinstance(scheduler, Client) else Client(str(scheduler))


def cluster_map(
    func: Callable[[Any], Any], items: Iterable[Any], scheduler: Any, *,
    drop: Callable[[int], bool] | None = None,
) -> Iterator[tuple[int, Any]]:
    """Run ``func(item)`` for every item on a Dask cluster, yielding as units finish.

    Parameters
    ----------
    func : callable
        A module-level function importable on every worker.
    items : iterable
        Picklable arguments, one unit each.
    scheduler : str or distributed.Client
        ``tcp://HOST:PORT`` of a running scheduler (a client is opened and closed here), or
        a connected client (left open).
    drop : callable, optional, keyword-only
        ``drop(position)`` true: that unit is no longer wanted (asked after each result):
        cancelled when still pending, its result (or error) never yielded.

    Yields
    ------
    (int, object)
        The item's position in ``items`` and ``func``'s result, in completion order.

    Raises
    ------
    OSError
        When the scheduler cannot be reached.
    Exception
        Whatever ``func`` raised on a worker, re-raised here (pending units are cancelled).
    """
    from distributed import as_completed

    client = connect(scheduler)
    try:
        futures = client.map(func, list(items), pure=False)
        position = {fut.key: i for i, fut in enumerate(futures)}
        done = as_completed(futures)
        del futures  # from here on only `done` holds the pending futures
        cancelled: set[Any] = set()
        try:
            for fut in done:
                checkpoint()
                if drop is not None and drop(position[fut.key]):
                    del fut  # not wanted any more: passed over, whatever it holds
                    continue
                result = fut.result()
                key = fut.key
                del fut  # release the result on the worker before handing it over
                yield position[key], result
                if drop is not None:
                    unwanted = [f for f in list(done.futures) if f.key not in cancelled
                                and drop(position[f.key])]
                    if unwanted:
                        cancelled.update(f.key for f in unwanted)
                        client.cancel(unwanted)
        finally:
            pending = list(done.futures)
            done.clear()
            if pending:
                client.cancel(pending)
    finally:
        if client is not scheduler:
            client.close()
