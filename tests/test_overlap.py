"""harness.core.overlap: produce here, consume on a worker, results in order, one item in flight."""

from __future__ import annotations

import threading

import pytest

from harness.core.overlap import overlapped


def test_results_in_item_order_with_consume_on_the_worker_and_inline_items_here():
    here = threading.get_ident()
    where = {}

    def consume(x):
        where[x] = threading.get_ident() == here
        return x * 10

    out = list(overlapped(range(6), lambda i: i, consume, inline=lambda x: x % 3 == 0))
    assert out == [0, 10, 20, 30, 40, 50]
    assert where == {0: True, 1: False, 2: False, 3: True, 4: False, 5: False}


def test_at_most_two_produced_items_alive_and_errors_end_the_loop_in_order():
    alive, peak = set(), [0]

    def produce(i):
        alive.add(i)
        peak[0] = max(peak[0], len(alive))
        return i

    def consume(i):
        alive.discard(i)
        if i == 3:
            raise ValueError("three")
        return i

    got = []
    with pytest.raises(ValueError, match="three"):
        for x in overlapped(range(10), produce, consume):
            got.append(x)
    assert got == [0, 1, 2] and peak[0] <= 2
