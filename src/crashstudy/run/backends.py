"""Execution backends: anything that maps a function over tasks and yields results as they finish.

Backends are small and interchangeable (a test runs each and compares with the in-process one):

- ``InProcess``: a plain loop in this process (the kernel itself uses every core through numba).
- ``ProcessPool``: ``--jobs N`` worker processes, each kernel limited to ``cores // N`` threads;
  the workers end when the main process ends, however it ends (:func:`_die_with_parent`).
- ``DaskBackend``: ``--scheduler tcp://HOST:PORT`` or ``local`` (a ``LocalCluster``); needs the
  ``dask`` extra. Workers compute; the client (this process) writes the files, or with ``--store zarr``
  the workers write their regions of the store (:mod:`crashstudy.results.regions`).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any, Protocol

from crashstudy import interrupt


class Backend(Protocol):
    def imap_unordered(self, fn: Callable[..., Any], tasks: Iterable[tuple[Any, ...]]) -> Iterator[Any]: ...

    def close(self) -> None: ...


class InProcess:
    """Run tasks one after the other in this process."""

    def imap_unordered(self, fn: Callable[..., Any], tasks: Iterable[tuple[Any, ...]]) -> Iterator[Any]:
        for t in tasks:
            yield fn(*t)

    def close(self) -> None:
        pass


def _die_with_parent(parent: int) -> None:
    """Pool initializer: end this worker when the process that started it ends, even by SIGKILL
    (a worker busy with a long chunk would otherwise run on for minutes, holding its memory).

    On Linux the kernel sends SIGKILL to the worker when its parent dies (``PR_SET_PDEATHSIG``);
    elsewhere, or if that call fails, a daemon thread polls ``os.getppid()`` twice a second. A parent
    that died before either was in place is seen at once (the worker's parent is no longer it)."""
    import signal
    import sys
    import threading
    import time

    armed = False
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            armed = libc.prctl(1, int(signal.SIGKILL), 0, 0, 0) == 0  # 1 = PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            armed = False
    if os.getppid() != parent:
        os._exit(1)
    if not armed:

        def watch() -> None:
            while os.getppid() == parent:
                time.sleep(0.5)
            os._exit(1)

        threading.Thread(target=watch, name="crashstudy-parent-watch", daemon=True).start()


def _call_limited(n_threads: int, fn: Callable[..., Any], args: tuple[Any, ...]) -> Any:
    from crashstudy.kernel.entry import set_threads

    set_threads(n_threads)
    return fn(*args)


class ProcessPool:
    """``jobs`` worker processes; at most ``2 * jobs`` tasks in flight (bounded memory)."""

    def __init__(self, jobs: int) -> None:
        import multiprocessing as mp

        self.jobs = jobs
        self.threads = max(1, (os.cpu_count() or 1) // jobs)
        self.pool = ProcessPoolExecutor(
            max_workers=jobs,
            mp_context=mp.get_context("spawn"),
            initializer=_die_with_parent,
            initargs=(os.getpid(),),
        )

    def imap_unordered(self, fn: Callable[..., Any], tasks: Iterable[tuple[Any, ...]]) -> Iterator[Any]:
        pending: set[Future[Any]] = set()
        it = iter(tasks)
        done_all = False
        while True:
            while not done_all and len(pending) < 2 * self.jobs:
                try:
                    t = next(it)
                except StopIteration:
                    done_all = True
                    break
                pending.add(self.pool.submit(_call_limited, self.threads, fn, t))
            if not pending:
                return
            finished: set[Future[Any]] = set()
            while not finished:  # wake up now and then: a stop request is acted on here, not in a lock
                interrupt.check()
                finished, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            for f in finished:
                yield f.result()

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


def make_backend(jobs: int = 1, scheduler: str | None = None) -> Backend:
    """The backend for the command-line options ``--jobs`` and ``--scheduler``."""
    if scheduler:
        from crashstudy.run.dask_backend import DaskBackend

        return DaskBackend(scheduler)
    if jobs > 1:
        return ProcessPool(jobs)
    return InProcess()
