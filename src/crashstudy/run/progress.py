"""The run's one status line on the terminal: variants done, variants/s, ETA."""

from __future__ import annotations

import sys
import time
from typing import Any


class Progress:
    """One status line (variants done, variants/s, ETA) on a terminal; a line per update when
    forced on into a file or pipe; silent otherwise. Before the first chunk ends the ETA is the
    run's ``estimate`` [s] (when known), never "inf"."""

    def __init__(
        self, total: int, enabled: bool | None = None, stream: Any = None, estimate: float | None = None
    ) -> None:
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.enabled = self.tty if enabled is None else enabled
        self.total, self.done, self.t0, self.last = total, 0, time.perf_counter(), 0.0
        self.first, self.estimate = 0, estimate

    def start(self, done: int) -> None:
        """``done`` variants were finished before this run (resume, reuse); show the line."""
        self.done = self.first = done
        self.last = -1.0
        self.update(0)

    def update(self, n: int) -> None:
        self.done += n
        now = time.perf_counter()
        if not self.enabled or (now - self.last < 0.2 and self.done < self.total):
            return
        self.last = now
        new = self.done - self.first
        if new > 0:
            rate = new / max(now - self.t0, 1e-9)
            text = f"{rate:,.0f} variants/s  ETA {(self.total - self.done) / rate:,.0f} s"
        elif self.estimate is not None:
            text = f"starting  ETA ~{max(self.estimate - (now - self.t0), 0.0):,.0f} s"
        else:
            text = "starting"
        line = f"  {self.done}/{self.total} variants  {text}"
        self.stream.write(f"\r{line}   " if self.tty else line + "\n")
        self.stream.flush()

    def close(self) -> None:
        if self.enabled and self.tty:
            self.stream.write("\n")
            self.stream.flush()
