"""Work shared among threads (:func:`tracker.core.workers.share`): every item once, whatever the pool is busy with."""
from __future__ import annotations

import threading

from tracker.core.workers import helper_pool, share


def test_every_item_is_worked_once_on_up_to_the_given_threads():
    done, names = [], set()
    lock = threading.Lock()

    def work(item: int) -> None:
        with lock:
            done.append(item)
            names.add(threading.current_thread().name)

    share(work, range(500), threads=3)
    assert sorted(done) == list(range(500)) and len(names) <= 3
    share(work, [], threads=2)  # nothing to do
    assert len(done) == 500


def test_a_busy_pool_does_not_hold_up_the_caller():
    """The helpers are shared by every caller (the filter's particles, the next frame's views): while another
    caller's work occupies them, share does all its items on the calling thread and returns without waiting for
    a helper that never started."""
    release = threading.Event()
    busy = helper_pool(1).submit(release.wait, 30)  # the one helper of two-thread runs, taken
    finished = threading.Event()
    done = []

    def caller() -> None:
        share(done.append, range(20), threads=2)
        finished.set()

    thread = threading.Thread(target=caller)
    thread.start()
    try:
        assert finished.wait(10), "share waited for a helper the pool had not started"
        assert sorted(done) == list(range(20))
    finally:
        release.set()
        thread.join(10)
        busy.result(10)
