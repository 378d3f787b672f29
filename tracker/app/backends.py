"""Where an experiment's runs execute: joblib worker processes (or this process, for one job), a Dask cluster or
a Ray cluster. :func:`run_all` hands each run to the chosen backend and yields the summaries as runs finish;
a run whose workers keep dying is one line (:func:`lost_worker`). What a run does is the caller's
(:func:`tracker.app.compare.execute_run`); the grid of runs is :mod:`tracker.app.run_grid`'s.
"""
from __future__ import annotations

from typing import Callable, Iterator

from tracker.app.run_grid import RunSpec
from tracker.core.errors import InputError
from tracker.engine.registry import Option

#: The backends ``compare --backend`` offers.
BACKENDS = ("joblib", "dask", "ray")
#: Where and how widely an experiment runs, declared once: ``compare``'s flags and :func:`tracker.compare`'s
#: keywords (and defaults) derive from them.
EXECUTION_OPTIONS: tuple[Option, ...] = (
    Option("jobs", int, 1, "parallel runs", minimum=1),
    Option("backend", str, "joblib", "joblib (this machine), dask or ray (a local cluster, or --address)",
           choices=BACKENDS),
    Option("address", str, None, "scheduler address of an existing Dask or Ray cluster"),
)


def execution_default(name: str):
    """The default of the execution setting ``name``."""
    return next(o.default for o in EXECUTION_OPTIONS if o.name == name)


def _ready() -> bool:
    """Imports a worker needs before its first run (the tracker, its plugins, torch)."""
    from tracker.app.api import available_priors

    available_priors()
    return True


def warm_joblib_workers(jobs: int):
    """Start joblib's worker processes and their imports in a background thread, so that they are ready when
    the runs start (they are reused by the next ``Parallel`` of the same size); returns the thread to join."""
    import threading

    from joblib import Parallel, delayed

    thread = threading.Thread(target=lambda: Parallel(n_jobs=jobs)(delayed(_ready)() for _ in range(jobs)),
                              daemon=True)
    thread.start()
    return thread


#: How often Ray runs a run again whose worker process died.
RAY_RETRIES = 3


def lost_worker(exc: BaseException) -> InputError:
    """The one line for a run whose workers kept dying (killed, out of memory) after the engine's retries."""
    reason = str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__
    return InputError(f"a run's worker died too often ({reason}); finished runs are kept: run the same compare "
                      "again to run only the missing ones")


def run_all(specs: list[RunSpec], jobs: int, backend: str, address: str | None,
            execute: Callable[[RunSpec], dict]) -> Iterator[dict]:
    """``execute(spec)`` for every run with the chosen backend (``jobs`` workers; ``address``: an existing Dask
    scheduler or Ray cluster), yielding each summary as it finishes (in any order). ``execute`` is a module-level
    function, so that worker processes find it by name."""
    if backend == "joblib":
        from joblib import Parallel, delayed

        if jobs == 1:
            for s in specs:
                yield execute(s)
            return
        yield from Parallel(n_jobs=jobs, return_as="generator_unordered")(delayed(execute)(s) for s in specs)
    elif backend == "dask":
        try:
            from distributed import Client, LocalCluster, as_completed
        except ImportError:
            raise InputError("--backend dask needs the dask extra: pip install '.[dask]'") from None
        from distributed import KilledWorker

        cluster = None if address else LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True,
                                                    dashboard_address=None)
        client = Client(address or cluster)
        try:
            # A run whose worker dies is given to another worker by the scheduler, up to its allowed failures
            # (distributed.scheduler.allowed-failures, 3 by default); then the experiment stops in one line.
            for future in as_completed(client.map(execute, specs, pure=False)):
                try:
                    yield future.result()
                except KilledWorker as exc:
                    raise lost_worker(exc) from None
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    elif backend == "ray":
        try:
            import ray
        except ImportError:
            raise InputError("--backend ray needs the ray extra: pip install '.[ray]'") from None
        started = not ray.is_initialized()
        if started:
            ray.init(address=address, num_cpus=None if address else jobs, include_dashboard=False,
                     log_to_driver=False, configure_logging=False)
        from ray.exceptions import RayTaskError, WorkerCrashedError

        try:
            # A run whose worker dies is run again by Ray (max_retries; an error the run raises is not retried).
            remote = ray.remote(num_cpus=1, max_retries=RAY_RETRIES)(execute)
            pending = [remote.remote(s) for s in specs]
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                try:
                    yield ray.get(done[0])
                except RayTaskError as exc:  # a bad input or a failed write: its one line, not Ray's traceback
                    if isinstance(getattr(exc, "cause", None), InputError):
                        raise exc.cause from None
                    raise
                except WorkerCrashedError as exc:
                    raise lost_worker(exc) from None
        finally:
            if started:
                ray.shutdown()
    else:
        raise InputError(f"unknown backend {backend!r}; choose from {', '.join(BACKENDS)}")
