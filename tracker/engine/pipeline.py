"""A sequence of frames through the filter: frames read and their observations prepared ahead, one step each.

The filter's step (:meth:`tracker.engine.filter.ParticleFilter.step`) tracks one frame; :func:`run_frames` feeds
it a sequence, records every step and calls the caller's callbacks between steps. With ``workers = 0`` it does
everything in the calling thread, one frame at a time. With ``workers > 0`` the steps run in a background
thread while the calling thread reads and prepares the next frame's observations, and ``workers - 1`` more
threads prepare frames further ahead (:class:`Prefetcher`). Preparing a frame draws no random numbers and the
steps run one at a time in frame order, so the results and the generator's draws do not depend on ``workers``.

This module knows the filter only as its step function, so that the filter (:mod:`tracker.engine.filter`)
can run a sequence through it without the two importing each other.
"""
from __future__ import annotations

import time
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace
from typing import Callable, Iterable, Iterator, Optional, TypeVar

from tracker.engine.likelihood import Frame, FrameLikelihood, Likelihood
from tracker.engine.recording import FrameStep, Recording

#: The filter's state carried from one frame to the next (:class:`tracker.engine.filter.FilterState`).
State = TypeVar("State")
#: One step of the filter: ``step(state, frame, load_seconds, prepared)`` -> the next state and the frame's
#: :class:`FrameStep`; ``prepared`` is the frame's likelihood already prepared, or None to prepare it in the step.
Step = Callable[[State, Frame, float, Optional[FrameLikelihood]], "tuple[State, FrameStep]"]


def run_frames(step: Step, state: State, frames: Iterable[Frame], likelihood: Likelihood, recording: Recording,
               on_frame: Callable[[FrameStep], None] | None = None,
               on_state: Callable[[State, Recording], None] | None = None, workers: int = 0) -> Recording:
    """Track ``frames`` from ``state`` with ``step``, adding every frame's :class:`FrameStep` (with its ``wall``
    time, seconds since the frame before was done, callbacks not counted) to ``recording``; returns it.

    ``on_frame(step)`` sees every frame's step and ``on_state(state, recording)`` the state after it, both in
    the calling thread between steps. ``workers`` as in the module docstring; ``likelihood`` prepares the
    frames read ahead (then a frame's ``load`` time is its reading and preparation, done while the frame before
    was filtered, and its ``observe`` time 0).
    """
    clock = [time.perf_counter()]  # when the frame before was done (its callbacks not counted)

    def finish(new_state: State, frame_step: FrameStep) -> State:
        frame_step = replace(frame_step, seconds={**frame_step.seconds, "wall": time.perf_counter() - clock[0]})
        recording.add(frame_step)
        if on_frame is not None:
            on_frame(frame_step)
        if on_state is not None:
            on_state(new_state, recording)
        clock[0] = time.perf_counter()
        return new_state

    if workers <= 0:
        with Prefetcher(frames, likelihood, 0) as source:
            while True:
                t0 = time.perf_counter()
                item = source.next()
                if item is None:
                    break
                state = finish(*step(state, item[0], time.perf_counter() - t0, item[1]))
        return recording
    # Pipelined: a filter thread steps frame t while this thread reads and prepares frame t+1 (image decoding
    # stays on this thread, see Prefetcher: its stderr redirection could swallow what the filter thread printed
    # meanwhile, which is nothing in normal operation), and the workers beyond the first prepare further ahead.
    # Steps run one at a time in frame order and every callback runs here between them, so the results and
    # the generator's draws are those of the loop above.
    with ThreadPoolExecutor(1, thread_name_prefix="filter") as stepper, \
            Prefetcher(frames, likelihood, workers - 1) as source:
        item, load = _next_prepared(source, likelihood)
        while item is not None:
            stepping = stepper.submit(step, state, item[0], load, item[1])
            try:
                following, load = _next_prepared(source, likelihood)
            except Exception as exc:  # raised once the frames before it are done, as in the loop above
                following, failure = None, exc
            else:
                failure = None
            state = finish(*stepping.result())
            if failure is not None:
                raise failure
            item = following
    return recording


def _next_prepared(source: "Prefetcher", likelihood: Likelihood
                   ) -> tuple[tuple[Frame, FrameLikelihood] | None, float]:
    """The next frame from ``source`` with its observations prepared (here, when ``source`` did not), and
    the seconds that took; None at the end."""
    t0 = time.perf_counter()
    item = source.next()
    if item is not None and item[1] is None:
        item = (item[0], likelihood.prepare(item[0]))
    return item, time.perf_counter() - t0


class Prefetcher:
    """Frames in order, each with its likelihood prepared ahead in background threads.

    The calling thread reads the frames (image decoding stays there: readers may briefly redirect the
    process's stderr to silence image libraries, which would swallow another thread's messages) up to
    ``workers`` frames ahead of the one it hands out, and ``workers`` threads prepare them with
    ``likelihood.prepare`` meanwhile. An exception raised while reading or preparing a frame is raised by
    :meth:`next` when that frame is due, so the frames before it are processed exactly as without
    prefetching. ``workers = 0`` reads frame by frame and leaves preparation to the caller. Use as a context
    manager (it stops the threads).
    """

    def __init__(self, frames: Iterable[Frame], likelihood: Likelihood, workers: int = 0):
        self.iterator: Iterator[Frame] = iter(frames)
        self.likelihood = likelihood
        self.workers = max(0, int(workers))
        self.pool = ThreadPoolExecutor(self.workers, thread_name_prefix="prepare") if self.workers else None
        self.pending: deque[tuple[Frame, Future] | BaseException] = deque()
        self.ended = False

    def __enter__(self) -> "Prefetcher":
        return self

    def __exit__(self, *exc) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=False, cancel_futures=True)

    def next(self) -> tuple[Frame, FrameLikelihood | None] | None:
        """The next frame with its prepared likelihood (None when not prefetching), or None at the end."""
        if self.pool is None:
            frame = next(self.iterator, None)
            return None if frame is None else (frame, None)
        if not self.pending:
            self._read()
        item = self.pending.popleft() if self.pending else None
        while len(self.pending) < self.workers and not self.ended:
            self._read()  # while the frame about to be handed out is still being prepared
        if item is None or isinstance(item, BaseException):
            if item is not None:
                raise item
            return None
        frame, future = item
        return frame, future.result()

    def _read(self) -> None:
        try:
            frame = next(self.iterator, None)
        except Exception as exc:  # raised when this frame is due
            self.ended = True
            self.pending.append(exc)
            return
        if frame is None:
            self.ended = True
        else:
            self.pending.append((frame, self.pool.submit(self.likelihood.prepare, frame)))
