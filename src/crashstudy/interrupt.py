"""A stop request from a signal, acted on at safe points.

The command line turns SIGINT and SIGTERM into a request (:func:`request`) instead of raising
``KeyboardInterrupt`` wherever the main thread happens to be: an exception raised inside
``concurrent.futures`` while it holds a lock can leave that lock held, and shutting the process pool
down then waits forever (seen once in CI: ``--jobs 2`` and SIGTERM). The runner checks the request
between chunks (:func:`check`) and the process pool while it waits for workers, and raises
``KeyboardInterrupt`` there, from its own code. A second signal raises at once.
"""

from __future__ import annotations

import threading
from typing import Any

from crashstudy.vocabulary.codes import KernelName

STOP = threading.Event()


def request(signum: int = 0, frame: Any = None) -> None:
    """Signal handler: ask the run to stop at the next safe point (a second request raises now)."""
    if STOP.is_set():
        raise KeyboardInterrupt
    STOP.set()


def check() -> None:
    """Raise ``KeyboardInterrupt`` if a stop was requested."""
    if STOP.is_set():
        raise KeyboardInterrupt


def reset() -> None:
    STOP.clear()


def compile_first(kernel: KernelName, batch: Any, histories: tuple[str, ...], vary: frozenset[int] | None) -> None:
    """Compile ``kernel`` for ``batch`` in a child process when it is not compiled yet, so that a stop
    request kills the compile at once (:func:`crashstudy.kernel.entry.compile_first` polls :func:`check`)."""
    from crashstudy.kernel.entry import compile_first as first

    first(kernel, batch, histories, vary, check)


class Stopped(KeyboardInterrupt):
    """A stop whose closing line (``note``) says what was kept and what can be continued."""

    def __init__(self, note: str) -> None:
        super().__init__(note)
        self.note = note
