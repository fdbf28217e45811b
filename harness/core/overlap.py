"""Producing the next item while the last one is consumed on a worker thread (:func:`overlapped`).

For loops whose two halves release the GIL at different times — a GL draw (the driver works in
``glFinish``) and a PNG encoding or a numba metric kernel — so that on two cores they run side by
side. One item is in flight at a time, so at most two produced items are alive at once.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

T = TypeVar("T")
P = TypeVar("P")
R = TypeVar("R")


def overlapped(items: Iterable[T], produce: Callable[[T], P], consume: Callable[[P], R], *,
               inline: Callable[[P], bool] = lambda made: False, name: str = "overlap") -> Iterator[R]:
    """``consume(produce(item))`` of each item, yielded in item order. ``produce`` runs on this thread,
    ``consume`` on one worker thread while the next item is produced; ``inline(made)`` true: that one is
    consumed here before the next is produced (e.g. an image too large to hold two of). An error of
    either half is raised here, in item order, and ends the loop."""
    with ThreadPoolExecutor(1, thread_name_prefix=name) as worker:
        pending = None
        for item in items:
            made = produce(item)
            if pending is not None:
                done, pending = pending, None
                yield done.result()
            if inline(made):
                yield consume(made)
            else:
                pending = worker.submit(consume, made)
            del made  # the worker's call holds it until consumed, not this frame
        if pending is not None:
            yield pending.result()
