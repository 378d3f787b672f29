"""How many threads numpy's BLAS, OpenCV, torch and the likelihood use: the number a run is given.

On a shared machine their defaults (one thread per core each, spinning while they wait) slow a run many
times over; parallel runs split the cores between them (:func:`share_of_cores`).
"""
from __future__ import annotations

import os
import sys

from tracker.core.errors import InputError


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity where the platform reports one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def share_of_cores(jobs: int) -> int:
    """Threads each of ``jobs`` parallel workers gets so that together they do not oversubscribe the cores."""
    return max(1, available_cores() // max(1, jobs))


#: The count last given to :func:`set_threads` (None: never called).
_configured: int | None = None


def configured_threads() -> int:
    """Threads this process may use: the count last given to :func:`set_threads`, else the available cores."""
    return available_cores() if _configured is None else _configured


def set_threads(n: int | None) -> int:
    """Limit BLAS (through threadpoolctl), OpenCV and torch to ``n`` threads (default: the available cores;
    torch now if it is imported, else once a learned prior, training, the GPU path or a run calls
    :func:`sync_torch_threads`); with ``n`` of 2 or more, tracking steps the filter in a background thread while the calling thread reads the
    next frame, and prepares frames further ahead in ``n - 2`` more (:func:`configured_threads`); the
    likelihood scores its blocks of particles on ``n`` threads (the filter's and ``n - 1`` helpers), while a run
    keeps numpy's BLAS on one (:func:`tracker.core.blas.serial_blas`). So up to ``n`` threads score, and the
    reading thread and the ``n - 2`` preparing ones may work at the same time, for the part of a frame that
    they overlap."""
    global _configured
    n = available_cores() if n is None else int(n)
    if n < 1:
        raise InputError(f"threads must be at least 1, got {n}")
    _configured = n
    from threadpoolctl import threadpool_limits

    threadpool_limits(n)
    import cv2

    cv2.setNumThreads(n)
    sync_torch_threads()
    return n


def sync_torch_threads() -> None:
    """Give torch the count of :func:`set_threads`, if it was called and torch has been imported by now (torch is
    imported only by what needs it: the learned priors, training, the GPU path; each calls this once it has)."""
    torch = sys.modules.get("torch")
    if torch is not None and _configured is not None and torch.get_num_threads() != _configured:
        torch.set_num_threads(_configured)
