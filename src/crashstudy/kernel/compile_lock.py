"""Who holds a compile lock, and whether a run should wait for them or compile what it needs itself.

A compile process (:mod:`crashstudy.kernel.warm`) takes an exclusive ``flock`` on the lock file in the
kernel folder and writes into it what it compiles (:func:`write_holder`): its pid, the kernels in order
with their keys (``generic``, ``criteria``, or a generated kernel's shape key) and the expected seconds
of each, and when it started. A run that needs a kernel while the lock is held (:func:`read_holder`)
waits only when the holder compiles that very kernel, is running (not stopped, not a zombie, not gone)
and is expected to finish it sooner than the run could compile it itself (:func:`plan_wait`); then
:func:`wait` polls until the lock is released, the kernel is ready, the holder dies or stops using
CPU (stuck), its CPU rate puts its end past the limit (slow: a niced compile on a loaded machine),
or the wait reaches the run's own compile time (or the holder's estimate with margin).
Otherwise the run compiles privately beside the holder: numba writes each cache file atomically
(a temporary file renamed into place), so two compiles of one kernel leave one valid entry.
"""

from __future__ import annotations

import fcntl
import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

POLL = 0.2  # [s] between looks at the lock while waiting
STUCK_AFTER = 3.0  # [s] without CPU time of the holder: it is stuck (a compile uses a core all the time)
MARGIN, SLACK = 1.5, 2.0  # a wait ends at SLACK + MARGIN x the holder's expected remaining seconds


@dataclass(frozen=True)
class Holder:
    """The process holding a compile lock and what it said it compiles (pid None: it said nothing)."""

    pid: int | None
    kernels: tuple[str, ...] = ()  # keys of the kernels it compiles, in order
    seconds: tuple[float, ...] = ()  # expected compile seconds of each
    started: float = 0.0  # [s] time.time() when it took the lock

    def remaining(self, key: str, now: float) -> float | None:
        """Expected seconds until kernel ``key`` is compiled (None: it does not compile it)."""
        if key not in self.kernels:
            return None
        done = self.started + sum(self.seconds[: self.kernels.index(key) + 1])
        return max(0.0, done - now)


def write_holder(fh: IO[str], kernels: list[str], seconds: list[float]) -> None:
    """Say in the (held) lock file ``fh`` what this process compiles."""
    fh.seek(0)
    fh.truncate()
    fh.write(json.dumps({"pid": os.getpid(), "kernels": kernels, "seconds": seconds, "started": time.time()}))
    fh.flush()


def read_holder(lock: Path) -> Holder | None:
    """The holder of ``lock``, or None when nobody holds it."""
    try:
        with open(lock, "a+") as fh:
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                fh.seek(0)
                return _parse(fh.read(4096))
            fcntl.flock(fh, fcntl.LOCK_UN)
            return None
    except OSError:  # no folder, not a regular file: nobody compiles there
        return None


def _parse(text: str) -> Holder:
    try:
        data: Any = json.loads(text)
        pid = int(data["pid"])
        kernels = tuple(str(k) for k in data["kernels"])
        seconds = tuple(float(s) for s in data["seconds"])
        return Holder(pid if pid > 0 else None, kernels, seconds, float(data["started"]))
    except (ValueError, TypeError, KeyError):
        return Holder(None)


def state(pid: int | None) -> tuple[str, float | None]:
    """("running" | "stopped" | "gone", CPU seconds used so far or None) of process ``pid``."""
    if pid is None:
        return "gone", None
    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
    except OSError:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return "gone", None
        except PermissionError:
            pass
        return "running", None  # no /proc: alive, CPU unknown
    code = fields[0]
    cpu = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    if code in ("Z", "X", "x"):
        return "gone", None
    return ("stopped" if code in ("T", "t") else "running"), cpu


def plan_wait(
    holder: Holder | None, key: str, own_seconds: float, now: float | None = None
) -> tuple[float, str]:
    """How long at most to wait for ``holder`` to compile kernel ``key`` (0: do not wait) and why, when
    compiling it here would take ``own_seconds``."""
    if holder is None:
        return 0.0, "free"
    if holder.pid is None:
        return 0.0, "the lock holder did not say what it compiles"
    run, _ = state(holder.pid)
    if run != "running":
        return (
            0.0,
            f"the lock holder (process {holder.pid}) is {'not running' if run == 'gone' else 'stopped'}",
        )
    left = holder.remaining(key, time.time() if now is None else now)
    if left is None:
        return 0.0, f"process {holder.pid} holds the compile lock for other kernels"
    if left >= own_seconds:
        return (
            0.0,
            f"process {holder.pid} compiles it too, expected in ~{left:.0f} s: compiling here is quicker",
        )
    return min(
        own_seconds, SLACK + MARGIN * left
    ), f"process {holder.pid} compiles it, expected in ~{left:.0f} s"


def wait(
    lock: Path,
    holder: Holder,
    limit: float,
    ready: Callable[[], bool],
    stop: Callable[[], None],
    key: str | None = None,
) -> str:
    """Wait at most ``limit`` seconds for ``holder`` to release ``lock``; why the wait ended: "ready",
    "released", "gone", "stopped", "stuck", "slow" or "limit". ``stop()`` raising (Ctrl-C) ends it at once.

    "slow": the holder's CPU time so far and its rate while waited for (a niced compile on a loaded
    machine gets a fraction of a core) put the end of kernel ``key`` (its expected seconds are CPU
    seconds) past ``limit``: compiling here is quicker."""
    t0 = time.monotonic()
    _, cpu = state(holder.pid)
    first_cpu, last_cpu, last_change = cpu, cpu, t0
    due = (
        None
        if key is None or key not in holder.kernels
        else sum(holder.seconds[: holder.kernels.index(key) + 1])
    )
    while True:
        stop()
        if ready():
            return "ready"
        if read_holder(lock) is None:
            return "ready" if ready() else "released"
        now = time.monotonic()
        run, cpu = state(holder.pid)
        if run != "running":
            return run
        if cpu is not None and (last_cpu is None or cpu > last_cpu + 0.01):
            last_cpu, last_change = cpu, now
        elif cpu is not None and now - last_change > STUCK_AFTER:
            return "stuck"
        if due is not None and cpu is not None and first_cpu is not None and now - t0 >= STUCK_AFTER:
            rate = (cpu - first_cpu) / (now - t0)  # [CPU s / s] the holder gets
            if rate > 0 and now - t0 + max(0.0, due - cpu) / rate > limit:
                return "slow"
        if now - t0 >= limit:
            return "limit"
        time.sleep(POLL)
