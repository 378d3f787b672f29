"""One-thread BLAS for the hot path's small matrix products.

The filter's and the likelihood's products are thin (``n x 4`` times ``4 x N``, weights times particles): a second
BLAS thread gains about 25 us per product on an idle machine, and on a busy one, where BLAS threads wait for
each other's cores, it measured 300 times slower (16 ms instead of 54 us). Worse, OpenBLAS's worker threads
spin after every parallel call (for about 0.1 s): during a filter step they took a core from the likelihood's
second thread (session 14: one spinning thread used 0.23 s of CPU per bodytrack frame of 4000 particles x 5
layers). Parallel work goes to blocks of particles and to frames instead.
"""
from __future__ import annotations

from functools import lru_cache

from threadpoolctl import ThreadpoolController


@lru_cache(maxsize=1)
def _blas() -> ThreadpoolController:
    """The BLAS libraries loaded when this is first called (finding them takes about 12 ms)."""
    return ThreadpoolController().select(user_api="blas")


def serial_blas():
    """Context in which the BLAS libraries this process had loaded when it was first used (numpy's, and any
    other imported by then) run on one thread; the setting from before comes back on exit.

    OpenBLAS has one thread pool per process, and threadpoolctl lets one thread set its size: the first to set
    it (usually the main thread; :func:`tracker.set_threads` does), whose regions nest like a stack. In other
    threads this context changes nothing, so regions of different threads cannot undo each other's setting;
    :meth:`tracker.engine.filter.ParticleFilter.run` opens it in the thread that calls it, for every thread of
    the run."""
    return _blas().limit(limits=1)
