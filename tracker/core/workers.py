"""Work shared among threads: the calling thread and helpers take the next item in turn.

The hot path's compiled loops and OpenCV's image functions release the interpreter lock, so threads that run
them work in parallel. The likelihood shares blocks of particles this way, the observations the views of a frame.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor, wait
from functools import lru_cache
from queue import Empty, SimpleQueue
from threading import Event
from typing import Callable, Iterable, TypeVar

Item = TypeVar("Item")


def share(work: Callable[[Item], None], items: Iterable[Item], threads: int) -> None:
    """``work(item)`` for every item, on ``threads`` threads: the calling one and ``threads - 1`` helpers take
    the next item in turn until none is left (so at most ``threads`` threads work, and a short last item does
    not hold up the others). ``work`` keeps its results itself (writing to disjoint places). An exception
    raised by any of them stops the others after their current item and is raised here."""
    todo: SimpleQueue = SimpleQueue()
    count = 0
    for item in items:
        todo.put(item)
        count += 1
    failed = Event()

    def drain() -> None:
        try:
            while not failed.is_set():
                try:
                    item = todo.get_nowait()
                except Empty:
                    return
                work(item)
        except BaseException:
            failed.set()
            raise

    n_helpers = min(threads, count) - 1
    helpers = [helper_pool(threads - 1).submit(drain) for _ in range(n_helpers)]
    try:
        drain()
    finally:
        # A helper that has not started (the pool busy with another caller's items: the filter's particles and
        # the next frame's views share it) is not waited for; those running are, so that no result is left to
        # a helper still writing it.
        started = [helper for helper in helpers if not helper.cancel()]
        wait(started)
    for helper in started:
        helper.result()


def helper_pool(n: int) -> ThreadPoolExecutor:
    """This process's pool of ``n`` helper threads (one per count)."""
    return _process_pool(n, os.getpid())


@lru_cache(maxsize=None)
def _process_pool(n: int, pid: int) -> ThreadPoolExecutor:
    """One pool per count and process: a child forked from a process that had a pool inherits the pool but not
    its threads, and its work would wait for them forever."""
    return ThreadPoolExecutor(n, thread_name_prefix="helper")
