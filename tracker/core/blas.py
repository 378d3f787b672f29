"""One-thread BLAS for the hot path's small matrix products.

The filter's and the likelihood's products are thin (``n x 4`` times ``4 x N``, weights times particles): a second
BLAS thread gains about 25 us per product on an idle machine, and on a busy one, where BLAS threads wait for
each other's cores, it measured 300 times slower (16 ms instead of 54 us). Worse, OpenBLAS's worker threads
spin after every parallel call (for about 0.1 s): during a filter step they took a core from the likelihood's
second thread (measured: one spinning thread used 0.23 s of CPU per bodytrack frame of 4000 particles x 5
layers). Parallel work goes to blocks of particles and to frames instead.
"""
from __future__ import annotations

import threading
from contextlib import contextmanager
from functools import lru_cache
from typing import Any, Iterator

from threadpoolctl import ThreadpoolController

_lock = threading.Lock()
#: :func:`serial_blas` regions open now, in every thread, and the limiter the first of them set.
_open = 0
_limiter: Any = None


@lru_cache(maxsize=1)
def _blas() -> ThreadpoolController:
    """The BLAS libraries loaded when this is first called (finding them takes about 12 ms)."""
    return ThreadpoolController().select(user_api="blas")


@contextmanager
def serial_blas() -> Iterator[None]:
    """Context in which the BLAS libraries this process had loaded when it was first used (numpy's, and any
    other imported by then) run on one thread.

    Regions may nest and overlap across threads: the first to open sets one thread, the last to close restores
    the setting from before, so no region runs with more while another is open. OpenBLAS has one pool per
    process, and threadpoolctl lets only one thread change it, the first that did (``tracker.set_threads`` and
    :meth:`tracker.engine.filter.ParticleFilter.run` usually run in the main thread): where the first or the last
    region of a period is in another thread, the setting may stay where it was, which costs speed, never
    results (the products split their outputs among threads, not their sums).
    """
    global _open, _limiter
    with _lock:
        if _open == 0:
            _limiter = _blas().limit(limits=1)
        _open += 1
    try:
        yield
    finally:
        with _lock:
            _open -= 1
            if _open == 0:
                _limiter.restore_original_limits()
                _limiter = None
