"""Writing a chunk's results while the next chunk computes (issue 25: the time outside the kernel).

The runner hands each finished chunk to :class:`WriteBehind`, which writes it on a thread of its own
(``ResultWriter.write``: netCDF / Zarr variables, the summary rows) while the main thread goes on with
the next chunk (its batch, the kernel). Both sides spend most of their time outside the GIL (the
compiled kernel, the HDF5 and Parquet writers), so on two cores the writes no longer add to the run's
time. At most one chunk is being written while the next one computes, as before (a chunk is handed
over only after the previous write ended): peak memory does not grow. Only the writer thread touches
the result files until :meth:`WriteBehind.close`; what it writes is what a write in the main thread
would write, bit for bit (tests/test_write_behind.py). An error of a write is raised in the main thread
at the next hand-over or at :meth:`close`.

Off by default (:data:`THREADED` False: each write in the runner's thread, the same files): measured at
load 7-8 on the 2-core machine the threaded 10^6 x 86-step run was not faster (wall 12.7 / 13.4 s against
11.6 / 12.5 s in the main thread; benchmarks/results/short_variants.md), and a crash of the HDF5 library
with a writer thread per run (a later run's garbage collection, in process) was avoided by one thread per
process without being understood. A quiet measurement decides whether it is switched on.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

THREADED = (
    False  # True: writes on the writer thread (off until a quiet 2-core measurement shows a gain: see below)
)
_POOL: list[ThreadPoolExecutor] = []  # the one writer thread of the process, started at the first run


def _writer_thread() -> ThreadPoolExecutor:
    """The process's writer thread: one for the process's life, never one per run (an HDF5 library
    that keeps state per thread saw that state end with each run's thread: a crash in a later run's
    garbage collection, tests/test_faults_disk.py's disk-full resume, in process)."""
    if not _POOL:
        _POOL.append(ThreadPoolExecutor(1, thread_name_prefix="crashstudy-writer"))
    return _POOL[0]


class WriteBehind:
    """Calls ``write(result)`` for each :meth:`put` result on one writer thread, one at a time, in order."""

    def __init__(self, write: Callable[[Any], None], threaded: bool | None = None) -> None:
        self._write = write
        self._pool = _writer_thread() if (THREADED if threaded is None else threaded) else None
        self._last: Future[Any] | None = None

    def put(self, result: Any) -> None:
        """Write ``result`` once the previous write has ended (raising that write's error, if any)."""
        self.wait()
        if self._pool is None:
            self._write(result)
        else:
            self._last = self._pool.submit(self._write, result)

    def call(self, fn: Callable[[], Any]) -> Future[Any]:
        """Run ``fn()`` on the writer thread after the write under way (e.g. create the result store
        while the kernels start); later writes come after it. Its result or error: the returned future."""
        self.wait()
        done: Future[Any] = Future()
        if self._pool is None:
            try:
                done.set_result(fn())
            except BaseException as exc:  # the caller's result() raises it, as from the thread
                done.set_exception(exc)
            return done
        self._last = done = self._pool.submit(fn)
        return done

    def wait(self) -> None:
        """Wait for the write under way; its error is raised here."""
        last, self._last = self._last, None
        if last is not None:
            last.result()

    def close(self) -> None:
        """Wait for the last write (raising its error); nothing is handed over after it."""
        try:
            self.wait()
        finally:
            self.stop()

    def stop(self) -> None:
        """Wait for the write under way, whatever it raised (the run is failing already:
        its own error is the one to report; the partial file stays consistent for ``--resume``)."""
        last, self._last = self._last, None
        if last is not None:
            with contextlib.suppress(BaseException):  # the caller's error is the one raised
                last.result()
        self._pool = None  # the thread stays for the next run
