"""A compile lock held by another process never strands a run on the NumPy reference: the run waits for
that process only when it compiles the very kernel the run needs and is expected to finish sooner than
compiling it here; a holder that is gone, stopped, stuck or busy with other kernels makes it compile
here at once (or after a bounded wait). Real processes hold the lock; the tests assert the decision and
which kernel was compiled or run, never a time. Background compiles are reaped (no zombies)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from crashstudy.arrays.batch import build_batch
from crashstudy.kernel import choice, compile_lock
from helpers import model_plan

MODEL = {
    "name": "lock-probe",
    "units": "SI",
    "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
    "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 100.0}}},
    "initial_velocity": {"b": [1.0]},
    "end_time": 0.05,
    "output": {"histories": "none"},
}

HOLDER = r"""
import fcntl, subprocess, sys, time
from crashstudy.kernel.compile_lock import write_holder
lock, mode, key, seconds, done = sys.argv[1:6]
fh = open(lock, "a+")
fcntl.flock(fh, fcntl.LOCK_EX)
write_holder(fh, [key], [float(seconds)])
if mode == "dead":  # the lock file names a process that has ended (the lock passed on to a survivor)
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    fh.seek(0); text = fh.read().replace('"pid": ', '"pid": %d, "old": ' % gone.pid, 1)
    fh.seek(0); fh.truncate(); fh.write(text); fh.flush()
print("held", flush=True)
if mode == "busy":  # compiling: uses a core until it is done
    t0 = time.time()
    while time.time() - t0 < 1.5:
        pass
    open(done, "w").close()
elif mode == "trickle":  # a niced compile on a loaded machine: a tenth of a core
    while True:
        t0 = time.time()
        while time.time() - t0 < 0.02:
            pass
        time.sleep(0.18)
else:
    time.sleep(120)
"""


@pytest.fixture
def setup(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):  # type: ignore[no-untyped-def]
    monkeypatch.setenv("CRASHSTUDY_KERNEL_CACHE", str(tmp_path / "kernels"))
    plan = model_plan(MODEL)
    batch, _ = build_batch(plan.topology, plan.params(0, 1), plan.interval)
    done = tmp_path / "done"
    started: list[tuple[tuple[str, ...], bool]] = []
    monkeypatch.setattr(choice, "generic_ready", lambda: done.exists())
    monkeypatch.setattr(
        choice,
        "start_background",
        lambda kernels, *a, must=False, **k: (
            started.append((kernels, must)) or subprocess.Popen([sys.executable, "-c", "pass"])
        ),
    )
    holders: list[subprocess.Popen[str]] = []

    def hold(mode: str, key: str = "generic", seconds: float = 5.0) -> subprocess.Popen[str]:
        lock = choice.cache_dir() / choice.LOCK_NAME
        proc = subprocess.Popen(
            [sys.executable, "-c", HOLDER, str(lock), mode, key, str(seconds), str(done)],
            stdout=subprocess.PIPE,
            text=True,
        )
        holders.append(proc)
        assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
        return proc

    yield batch, plan, hold, started, done
    for proc in holders:
        proc.kill()
        proc.wait()


def test_a_run_waits_for_another_process_compiling_the_kernel_it_needs(setup) -> None:  # type: ignore[no-untyped-def]
    batch, plan, hold, started, done = setup
    hold("busy", "generic", 5.0)  # expected in ~5 s, compiling here would take GENERIC_COMPILE (41 s)
    said: list[str] = []
    choice.compile_foreground(
        ("generic",), batch, plan.topology.histories, None, lambda: None, say=said.append
    )
    assert started == [] and done.exists(), "it waited and compiled nothing itself"
    assert (
        said[0].startswith("waiting for the generic kernel: process ")
        and f"~{choice.GENERIC_COMPILE:.0f} s" in said[0]
    )


@pytest.mark.parametrize(("mode", "why"), [("dead", "is not running"), ("stop", "is stopped")])
def test_a_lock_of_a_dead_or_stopped_process_makes_the_run_compile_at_once(
    setup, mode: str, why: str
) -> None:  # type: ignore[no-untyped-def]
    batch, plan, hold, started, done = setup
    holder = hold("dead" if mode == "dead" else "busy")
    if mode == "stop":
        os.kill(holder.pid, signal.SIGSTOP)
        for _ in range(100):  # the signal is delivered asynchronously
            if _proc_state(holder.pid) in ("T", "t"):
                break
            time.sleep(0.05)
    said: list[str] = []
    choice.compile_foreground(
        ("generic",), batch, plan.topology.histories, None, lambda: None, say=said.append
    )
    assert started == [(("generic",), True)], "compiled here, even with the lock held"
    assert len(said) == 1 and said[0].startswith("compiling the generic kernel here") and why in said[0]
    if mode == "stop":
        os.kill(holder.pid, signal.SIGCONT)


def test_a_stuck_holder_is_waited_for_only_until_it_shows_no_progress(setup) -> None:  # type: ignore[no-untyped-def]
    batch, plan, hold, started, done = setup
    hold("sleep", "generic", 5.0)  # alive, says it compiles the generic kernel, uses no CPU
    limit, _ = compile_lock.plan_wait(
        compile_lock.read_holder(choice.cache_dir() / choice.LOCK_NAME), "generic", choice.GENERIC_COMPILE
    )
    assert 0 < limit <= choice.GENERIC_COMPILE  # never longer than compiling it here
    said: list[str] = []
    choice.compile_foreground(
        ("generic",), batch, plan.topology.histories, None, lambda: None, say=said.append
    )
    assert started == [(("generic",), True)] and not done.exists()
    assert said[0].startswith("waiting for") and said[1] == (
        f"stopped waiting (the holder uses no CPU); compiling the generic kernel here (~{choice.GENERIC_COMPILE:.0f} s)"
    )


def test_a_holder_that_gets_too_little_cpu_to_finish_first_is_not_waited_for_long(setup) -> None:  # type: ignore[no-untyped-def]
    """Expected in ~20 CPU-s, but it gets a tenth of a core: it would end in ~200 s, later than compiling here."""
    batch, plan, hold, started, done = setup
    hold("trickle", "generic", 20.0)
    said: list[str] = []
    choice.compile_foreground(
        ("generic",), batch, plan.topology.histories, None, lambda: None, say=said.append
    )
    assert started == [(("generic",), True)] and said[0].startswith("waiting for")
    assert said[1].startswith("stopped waiting (at the CPU share it gets, the holder would finish later")


def test_a_holder_compiling_other_kernels_is_not_waited_for(setup) -> None:  # type: ignore[no-untyped-def]
    batch, plan, hold, started, done = setup
    hold("busy", "k_0123456789abcdef0123", 2.0)  # another model shape's generated kernel
    said: list[str] = []
    choice.compile_foreground(
        ("generic",), batch, plan.topology.histories, None, lambda: None, say=said.append
    )
    assert started == [(("generic",), True)] and "holds the compile lock for other kernels" in said[0]


def test_a_holder_expected_later_than_the_own_compile_is_not_waited_for(setup) -> None:  # type: ignore[no-untyped-def]
    batch, plan, hold, started, done = setup
    hold("busy", "generic", 10 * choice.GENERIC_COMPILE)
    said: list[str] = []
    choice.compile_foreground(
        ("generic",), batch, plan.topology.histories, None, lambda: None, say=said.append
    )
    assert started == [(("generic",), True)] and "compiling here is quicker" in said[0]


def test_a_long_run_is_never_committed_to_the_reference_because_another_process_holds_the_lock(
    setup, monkeypatch: pytest.MonkeyPatch
) -> None:  # type: ignore[no-untyped-def]
    """Before: pick() returned the reference whenever any process held the lock (a 426-mass grid ran
    > 10 min on it instead of ~25 s on the generic kernel)."""
    batch, plan, hold, started, done = setup
    monkeypatch.setattr(choice, "generated_ready", lambda *a: False)
    hold("sleep", "k_0123456789abcdef0123", 30.0)
    long_batch = batch.take(np.zeros(8, dtype=np.int64))
    long_batch.n_steps[:] = int(2 * choice.GENERIC_COMPILE / (choice.REF_STEP + choice.REF_SPRING_STEP))
    t_ref = choice.reference_seconds(float(long_batch.n_steps.max()), 1, float(long_batch.n_steps.sum()))
    assert t_ref > choice.GENERIC_COMPILE
    assert choice.pick(long_batch, (), None) in ("generated", "generic")


def _proc_state(pid: int) -> str | None:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0]
    except OSError:
        return None


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads process states from /proc")
def test_finished_background_compiles_are_reaped(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Before: a finished background compile stayed a zombie until the run's process exited."""
    monkeypatch.setenv("CRASHSTUDY_KERNEL_CACHE", str(tmp_path / "kernels"))
    plan = model_plan(MODEL)
    batch, _ = build_batch(plan.topology, plan.params(0, 1), plan.interval)
    lock = choice.cache_dir() / choice.LOCK_NAME
    with open(lock, "a+") as fh:  # held here: the background job exits at once without compiling
        import fcntl

        fcntl.flock(fh, fcntl.LOCK_EX)
        proc = choice.start_background(("generic",), batch, plan.topology.histories, None)
        assert proc is not None
        states = []
        for _ in range(600):
            states.append(_proc_state(proc.pid))
            if states[-1] in (None, "Z"):
                break
            time.sleep(0.1)
        time.sleep(0.5)  # a reaper has had its chance
        assert _proc_state(proc.pid) is None, f"process {proc.pid} is left as {_proc_state(proc.pid)!r}"
