"""Dask backend: chunks computed on a Dask cluster; the results written by the client (this process),
or, with ``--store zarr``, by the workers into the store at its shared path.

``--scheduler tcp://HOST:PORT`` connects to a running scheduler (``dask scheduler`` and ``dask worker``
started by the user, see ``docs/dask.md``); ``--scheduler local`` starts a two-worker ``LocalCluster`` on
the loopback interface for the run and stops it after. Workers compute :func:`crashstudy.run.runner.run_chunk`
and send back a :class:`~crashstudy.results.chunk_result.ChunkResult` that the client writes; with ``--store zarr``
each task (:func:`crashstudy.results.regions.write_region`) writes its chunk's region of ``results.zarr.partial``
and sends back a small :class:`~crashstudy.results.regions.Receipt` (the backend maps whatever function
it is given).

Needs the optional extra ``pip install 'crashstudy[dask]'``; without it, constructing the backend raises
:class:`~crashstudy.errors.InputError` (the command line exits with code 2 and says what to install).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from crashstudy.errors import InputError, Problem

LOCAL = "local"
LOCAL_WORKERS = 2  # worker processes of ``--scheduler local``
CONNECT_TIMEOUT = 10.0  # seconds to reach a remote scheduler
IN_FLIGHT_PER_THREAD = 2  # tasks submitted but not yet returned, per worker thread
_END = object()
MISSING = "the Dask backend needs the optional extra: pip install 'crashstudy[dask]'"


def _problem(message: str) -> InputError:
    return InputError([Problem("--scheduler", None, "", message)])


def _call_on_worker(fn: Callable[..., Any], args: tuple[Any, ...]) -> Any:
    """Run ``fn(*args)`` on a Dask worker with the kernel limited to the worker's share of threads.

    A worker started with ``--nthreads T`` runs up to ``T`` tasks at once; a task sets the compiled
    kernel's thread count (:func:`crashstudy.kernel.entry.set_threads`, one setting per worker
    process) to ``T`` divided by the number of tasks running on that worker as it starts (at least 1):
    a worker of one thread computes with one thread, a lone task on a ``T``-thread worker with ``T``.
    """
    from distributed import get_worker

    from crashstudy.kernel.entry import set_threads

    try:
        state = get_worker().state
        n = max(1, state.nthreads // max(1, state.executing_count))
    except ValueError:  # not on a worker (e.g. called directly in a test)
        n = 1
    set_threads(n)
    return fn(*args)


class NoAnswer(TimeoutError):
    """The address accepted a connection but sent no Dask handshake in time."""


def _handshake(address: str, timeout: float) -> None:
    """Connect to ``address`` and exchange Dask's handshake within ``timeout`` seconds, then disconnect.

    ``distributed.Client`` bounds the TCP connection by its timeout but waits for the handshake without
    one: a listener that accepts and never answers held it for good. This runs the same connection in
    a thread of its own and gives up about 1 s after ``timeout`` (raising :class:`NoAnswer`).
    """
    import asyncio
    import threading

    from distributed.comm import connect

    async def attempt() -> None:
        comm = await connect(address, timeout=timeout)
        await comm.close()

    failure: list[BaseException] = []
    silent = "it accepted the connection but sent no Dask handshake (is it a Dask scheduler?)"

    def target() -> None:
        try:
            asyncio.run(asyncio.wait_for(attempt(), timeout + 1.0))  # connect() gives up at `timeout` itself
        except asyncio.TimeoutError:
            failure.append(NoAnswer(silent))
        except BaseException as exc:  # reported by the caller, in its thread
            failure.append(exc)

    thread = threading.Thread(target=target, name="crashstudy-dask-handshake", daemon=True)
    thread.start()
    thread.join(timeout + 3.0)  # asyncio.wait_for ends it at `timeout` + 1 s; 2 s more for the loop to close
    if thread.is_alive():
        raise NoAnswer(silent)
    if failure:
        raise failure[0]


class DaskBackend:
    """Map a function over tasks on a Dask cluster, yielding results as they finish.

    Parameters
    ----------
    scheduler : str
        ``"local"``: start a ``distributed.LocalCluster`` on 127.0.0.1 with 2 worker processes of one
        thread each, no dashboard, closed by :meth:`close`. Otherwise the address of a running
        scheduler, e.g. ``"tcp://10.0.0.5:8786"``.
    timeout : float, optional
        Seconds to wait for a remote scheduler before giving up with :class:`InputError`
        (default :data:`CONNECT_TIMEOUT`, 10 s): for the connection and for its answer.
    n_workers : int, default 2
        Worker processes of the local cluster (ignored for a remote scheduler).

    Raises
    ------
    InputError
        When ``distributed`` is not installed, or the scheduler cannot be reached.

    Notes
    -----
    At most ``2 x`` (total worker threads, re-read as results arrive; at least 2) tasks are in flight,
    so a study of many chunks is never submitted at once and at most that many chunk results wait in
    worker memory. A task whose worker dies is recomputed elsewhere by the scheduler (up to
    ``distributed.scheduler.allowed-failures`` times); since each chunk is a pure function of the plan
    and its variant range, the results are the same.
    """

    def __init__(self, scheduler: str, timeout: float | None = None, n_workers: int = LOCAL_WORKERS) -> None:
        timeout = CONNECT_TIMEOUT if timeout is None else timeout
        try:
            import distributed
        except ImportError:
            raise _problem(MISSING) from None
        self._distributed = distributed
        self.scheduler = scheduler
        self.cluster: Any = None
        if scheduler == LOCAL:
            self.cluster = distributed.LocalCluster(
                host="127.0.0.1",
                n_workers=n_workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.ERROR,
                # no dashboard; the scheduler's small HTTP server (health, metrics) still starts, and would
                # take the fixed port 8787 (a warning when two runs overlap): a free loopback port instead
                scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
            )
            try:
                self.client = distributed.Client(self.cluster, set_as_default=False)
            except BaseException:
                self.cluster.close()
                raise
            return
        try:
            _handshake(scheduler, timeout)
            self.client = distributed.Client(scheduler, timeout=timeout, set_as_default=False)
        except Exception as exc:  # refused, timed out, malformed address, or not a Dask scheduler
            raise _problem(
                f"cannot connect to a Dask scheduler at {scheduler!r} (waited up to {timeout:g} s): "
                f"{type(exc).__name__}: {exc}; give 'local', or the address that `dask scheduler` prints "
                "(tcp://HOST:PORT, default port 8786)"
            ) from None

    def worker_threads(self) -> int:
        """Total threads of the workers connected now (0 before any worker has joined)."""
        return int(sum(self.client.nthreads().values()))

    def _limit(self) -> int:
        return IN_FLIGHT_PER_THREAD * max(1, self.worker_threads())

    def imap_unordered(self, fn: Callable[..., Any], tasks: Iterable[tuple[Any, ...]]) -> Iterator[Any]:
        """Submit ``fn(*t)`` for each ``t`` in ``tasks`` (a bounded number at a time); yield results as they finish."""
        it = iter(tasks)
        limit = self._limit()
        running = self._distributed.as_completed(loop=self.client.loop)
        in_flight = 0
        exhausted = False
        try:
            while True:
                while not exhausted and in_flight < limit:
                    t = next(it, _END)
                    if t is _END:
                        exhausted = True
                        break
                    running.add(self.client.submit(_call_on_worker, fn, t, pure=False))
                    in_flight += 1
                if in_flight == 0:
                    return
                future = next(running)
                in_flight -= 1
                result = future.result()
                future.release()
                del future
                yield result
                limit = self._limit()  # workers may have joined or left
        finally:
            running.clear()

    def close(self) -> None:
        """Cancel what is still running, close the client and the local cluster if this backend started one."""
        try:
            self.client.close()
        finally:
            if self.cluster is not None:
                self.cluster.close()
                self.cluster = None
