"""Timing helpers shared by the benchmark scripts (each call is warmed up once first)."""
from __future__ import annotations

import statistics
import time
from typing import Callable


def mean_ms(fn: Callable[[], object], repeats: int) -> float:
    """Mean wall time of ``fn()`` in milliseconds over ``repeats`` calls."""
    fn()
    t0 = time.perf_counter()
    for _ in range(repeats):
        fn()
    return (time.perf_counter() - t0) / repeats * 1000.0


def _times(fn: Callable[[], object], repeats: int) -> list[float]:
    """Wall times (seconds) of ``repeats`` calls of ``fn()`` after one warm-up call."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return times


def best_ms(fn: Callable[[], object], repeats: int = 5) -> float:
    """Fastest wall time of ``fn()`` in milliseconds over ``repeats`` calls (robust to a busy machine)."""
    return min(_times(fn, repeats)) * 1000.0


def median_ms(fn: Callable[[], object], repeats: int = 20) -> tuple[float, float, float]:
    """Median, fastest and slowest wall time of ``fn()`` in milliseconds over ``repeats`` calls."""
    times = _times(fn, repeats)
    return statistics.median(times) * 1000.0, min(times) * 1000.0, max(times) * 1000.0
