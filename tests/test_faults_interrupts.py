"""Faults, with real processes: interrupted runs (SIGINT, SIGTERM, SIGKILL) and a worker process killed
mid-study (issue 5, item 4), and an unfinished run that is neither resumed nor forced, or resumed onto
another study's partial result.

The contract under test (docs/studies.md, issue 5) and the shared fault study are described in
fault_runs.py."""

from __future__ import annotations

import fcntl
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import netCDF4
import numpy as np
import psutil
import pytest
import xarray as xr

from fault_runs import (
    FAULT_STUDY,
    assert_clean_message,
    assert_identical,
    assert_no_complete_result,
    load,
)
from helpers import run_cli as cli  # the command line in this process (helpers.run_cli)

N_VARIANTS = 500
CHUNK = 83  # chunk_size() of FAULT_STUDY: 256 MiB / (8 B * 100 001 samples * 4 energies)


# ------------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------------


def default_sigint() -> None:
    """In the child: Ctrl-C's SIGINT handled as in a terminal. A test run started from a script in the
    background inherits SIGINT ignored (the shell's rule for background jobs), and Python then never
    raises KeyboardInterrupt; the interrupt tests need the user's situation."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


class Run:
    """``crashstudy run`` in the background, its progress line read as it comes."""

    def __init__(self, study: Path, out: Path, *extra: str) -> None:
        self.out = out
        self.proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "crashstudy.cli",
                "run",
                str(study),
                "-o",
                str(out),
                "--progress",
                "on",
                *extra,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            preexec_fn=default_sigint,
        )
        assert self.proc.stderr is not None
        flags = fcntl.fcntl(self.proc.stderr, fcntl.F_GETFL)
        fcntl.fcntl(self.proc.stderr, fcntl.F_SETFL, flags | os.O_NONBLOCK)
        self.err = b""

    def _read(self) -> None:
        assert self.proc.stderr is not None
        try:
            chunk = self.proc.stderr.read()
        except BlockingIOError:
            chunk = None
        if chunk:
            self.err += chunk

    def done(self) -> int:
        """Variants reported finished so far (the progress line is updated after each chunk is written)."""
        self._read()
        found = re.findall(rb"(\d+)/%d variants" % N_VARIANTS, self.err)
        return int(found[-1]) if found else 0

    def wait_for(self, condition, what: str, timeout: float = 240) -> None:  # type: ignore[no-untyped-def]
        t0 = time.monotonic()
        while not condition():
            if self.proc.poll() is not None:
                self._read()
                pytest.fail(
                    f"the run ended (exit {self.proc.returncode}) before {what}:\n{self.err.decode()[-2000:]}"
                )
            if time.monotonic() - t0 > timeout:
                self.proc.kill()
                pytest.fail(f"timed out waiting for {what}")
            time.sleep(0.005)

    def wait_chunks(self, n: int) -> int:
        self.wait_for(
            lambda: self.done() >= n * CHUNK and (self.out / "results.nc.partial").exists(),
            f"{n} chunks were written",
        )
        return self.done()

    def finish(self, timeout: float = 240) -> tuple[int, str, str]:
        out, err = self.proc.communicate(timeout=timeout)
        return self.proc.returncode, out.decode(), (self.err + err).decode()


def done_in_partial(out: Path) -> int:
    with netCDF4.Dataset(out / "results.nc.partial") as nc:
        return int(np.asarray(nc.variables["done"][:]).sum())


def test_fault_study_writes_many_chunks(fault_dir: Path) -> None:
    from crashstudy.run.runner import chunk_size
    from crashstudy.study.plan import load_study

    plan = load_study(fault_dir / "study.yaml")
    assert plan.n_variants == N_VARIANTS and chunk_size(plan) == CHUNK


# ------------------------------------------------------------------------------------------------
# interrupted runs: SIGINT, SIGTERM, SIGKILL
# ------------------------------------------------------------------------------------------------


@dataclass
class Interrupted:
    """A run of the fault study stopped by a signal once two chunks were reported written."""

    rc: int
    err: str
    seen: int  # variants the progress line had reported finished when the signal was sent
    out: Path


def interrupt(fault_dir: Path, out: Path, sig: signal.Signals, jobs: int = 1) -> Interrupted:
    run = Run(fault_dir / "study.yaml", out, "--jobs", str(jobs))
    seen = run.wait_chunks(2)
    run.proc.send_signal(sig)
    rc, _, err = run.finish()
    return Interrupted(rc, err, seen, out)


@pytest.fixture(scope="module")
def ctrl_c(fault_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Interrupted:
    """One run stopped by Ctrl-C (SIGINT): the SIGINT case below, and the unfinished folder the tests of
    a run without --resume and of a resume with another study start from; each test works on a copy."""
    return interrupt(fault_dir, tmp_path_factory.mktemp("ctrl-c") / "out", signal.SIGINT)


def copy_of(run: Interrupted, tmp_path: Path) -> Path:
    return Path(shutil.copytree(run.out, tmp_path / "out"))


@pytest.mark.parametrize(
    ("sig", "jobs"),
    [(signal.SIGINT, 1), (signal.SIGTERM, 1), (signal.SIGKILL, 1), (signal.SIGTERM, 2)],
    ids=["SIGINT", "SIGTERM", "SIGKILL", "SIGTERM-jobs2"],
)
def test_interrupted_run_leaves_partial_only_and_resumes_identically(
    fault_dir: Path,
    reference: tuple[xr.Dataset, Path],
    tmp_path: Path,
    sig: signal.Signals,
    jobs: int,
    request: pytest.FixtureRequest,
) -> None:
    if sig == signal.SIGINT:  # the module's Ctrl-C run, shared with the tests of its unfinished folder
        run: Interrupted = request.getfixturevalue("ctrl_c")
        out = copy_of(run, tmp_path)
    else:
        run = interrupt(fault_dir, tmp_path / "out", sig, jobs)
        out = run.out
    rc, err, seen = run.rc, run.err, run.seen
    if sig == signal.SIGKILL:
        assert rc == -signal.SIGKILL
    else:
        assert rc == 130, err
        assert_clean_message(err)
        assert "interrupted" in err and "--resume" in err, err  # says how to continue
    # a SIGKILL leaves the lock file of the folder (.crashstudy.lock; the lock itself died with the run)
    assert sorted(p.name for p in out.iterdir() if p.name != ".crashstudy.lock") == ["results.nc.partial"]
    assert sig == signal.SIGKILL or not (out / ".crashstudy.lock").exists()
    assert_no_complete_result(out)
    kept = done_in_partial(out)
    assert seen <= kept < N_VARIANTS  # every chunk reported finished is in the partial file

    p = cli("run", fault_dir / "study.yaml", "-o", out, "--resume", "--progress", "off")
    assert p.returncode == 0, p.stderr
    assert f"({N_VARIANTS - kept} variants computed" in p.stdout, p.stdout  # only the missing ones ran
    assert sorted(x.name for x in out.iterdir()) == [
        "manifest.json",
        "results.nc",
        "summary.csv",
        "summary.parquet",
    ]
    assert_identical(load(out), reference[0], out, reference[1])


def test_sigkill_before_the_first_chunk_is_written_resumes(
    fault_dir: Path, reference: tuple[xr.Dataset, Path], tmp_path: Path
) -> None:
    out = tmp_path / "out"
    run = Run(fault_dir / "study.yaml", out)
    run.wait_for(lambda: (out / "results.nc.partial").exists(), "results.nc.partial exists")
    assert run.done() == 0
    run.proc.kill()
    rc, _, _ = run.finish()
    assert rc == -signal.SIGKILL
    assert_no_complete_result(out)
    p = cli("run", fault_dir / "study.yaml", "-o", out, "--resume", "--progress", "off")
    assert "Traceback" not in p.stderr, p.stderr[-1500:]
    assert p.returncode == 0, p.stderr
    assert_identical(load(out), reference[0], out, reference[1])


# ------------------------------------------------------------------------------------------------
# a worker process killed mid-study (--jobs 2)
# ------------------------------------------------------------------------------------------------


@dataclass
class Outcome:
    rc: int
    err: str
    files: list[str]
    kept: int
    resume: subprocess.CompletedProcess[str]
    out: Path


def _pool_workers(pid: int) -> list[psutil.Process]:
    kids = psutil.Process(pid).children()
    return [
        k
        for k in kids
        if "spawn_main" in " ".join(k.cmdline()) and "resource_tracker" not in " ".join(k.cmdline())
    ]


@pytest.fixture(scope="module")
def worker_killed(fault_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Outcome:
    out = tmp_path_factory.mktemp("worker") / "out"
    run = Run(fault_dir / "study.yaml", out, "--jobs", "2")
    run.wait_chunks(2)
    run.wait_for(lambda: len(_pool_workers(run.proc.pid)) == 2, "two pool workers run")
    victim = _pool_workers(run.proc.pid)[0]
    os.kill(victim.pid, signal.SIGKILL)
    rc, _, err = run.finish()
    files = sorted(p.name for p in out.iterdir())
    kept = done_in_partial(out) if "results.nc.partial" in files else -1
    # resumed in this process: its subject is the partial file the killed worker's run left (a --jobs 2
    # resume is TestProcessPool's in test_backends); a pool here started 2 more worker processes
    resume = cli("run", fault_dir / "study.yaml", "-o", out, "--resume", "--progress", "off")
    return Outcome(rc, err, files, kept, resume, out)


def test_killed_worker_fails_the_run_and_resume_completes_identically(
    worker_killed: Outcome, reference: tuple[xr.Dataset, Path]
) -> None:
    o = worker_killed
    assert o.rc not in (0, 130), o.err  # the run fails, it does not pretend to be complete or interrupted
    assert o.files == ["results.nc.partial"]
    assert 2 * CHUNK <= o.kept < N_VARIANTS
    assert o.resume.returncode == 0, o.resume.stderr
    assert f"({N_VARIANTS - o.kept} variants computed" in o.resume.stdout
    assert_identical(load(o.out), reference[0], o.out, reference[1])


def test_killed_worker_is_reported_in_one_message_without_traceback(worker_killed: Outcome) -> None:
    assert_clean_message(worker_killed.err)
    assert "--resume" in worker_killed.err


def test_unfinished_run_is_not_restarted_without_resume_or_force(
    fault_dir: Path, ctrl_c: Interrupted, tmp_path: Path
) -> None:
    assert ctrl_c.rc == 130, ctrl_c.err
    out = copy_of(ctrl_c, tmp_path)
    data = (out / "results.nc.partial").read_bytes()
    p = cli("run", fault_dir / "study.yaml", "-o", out, "--progress", "off")
    assert p.returncode == 2, p.stderr
    assert_clean_message(p.stderr)
    assert "--resume" in p.stderr and "--force" in p.stderr
    assert (out / "results.nc.partial").read_bytes() == data
    assert sorted(x.name for x in out.iterdir()) == ["results.nc.partial"]


def test_resume_onto_another_studys_partial_is_a_clear_input_error(
    fault_dir: Path, ctrl_c: Interrupted, tmp_path: Path
) -> None:
    assert ctrl_c.rc == 130, ctrl_c.err
    out = copy_of(ctrl_c, tmp_path)
    changed = fault_dir / "changed.yaml"
    changed.write_text(FAULT_STUDY.replace("impact_velocity: [1.0,", "impact_velocity: [1.25,"))
    data = (out / "results.nc.partial").read_bytes()
    p = cli("run", changed, "-o", out, "--resume", "--progress", "off")
    assert (out / "results.nc.partial").read_bytes() == data  # kept for the study it belongs to
    assert p.returncode == 2, p.stderr[-1500:]
    assert_clean_message(p.stderr)
    assert "--force" in p.stderr
