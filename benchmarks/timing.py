"""Timing helpers shared by the benchmark scripts (each call is warmed up once first)."""
from __future__ import annotations

import time
from typing import Callable


def mean_ms(fn: Callable[[], object], repeats: int) -> float:
    """Mean wall time of ``fn()`` in milliseconds over ``repeats`` calls."""
    fn()
    t0 = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - t0) / repeats * 1000.0


def best_ms(fn: Callable[[], object], repeats: int = 5) -> float:
    """Fastest wall time of ``fn()`` in milliseconds over ``repeats`` calls (robust to a busy machine)."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times) * 1000.0
