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
    return ThreadpoolController().select(user_api="blas")


def serial_blas():
    """Context in which the BLAS libraries numpy and scipy load run on one thread (restored on exit)."""
    return _blas().limit(limits=1)
