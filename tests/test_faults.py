"""Faults, with real processes and real files: interrupted runs, a killed worker, a read-only or full disk,
paths, and YAML attacks through the command line (issue 5, item 4).

The contract under test (docs/studies.md, issue 5): an interrupted or failed run never leaves a ``results.nc`` (only
``results.nc.partial``, which ``crashstudy summary`` and ``open_results`` refuse), says what happened in a
short message without a traceback, and ``crashstudy run --resume`` then completes with results identical to
an uninterrupted run, variable by variable (NaN where the reference has NaN) and attribute by attribute.

The interrupted study (``FAULT_STUDY``) is 500 variants of a one-spring model with ``histories: none`` and
a 2e-5 s history interval over 2 s: the kernel's per-variant energy buffer (100 001 samples) keeps chunks
at 83 variants, so the run writes 7 chunks in a few seconds and a signal can land between chunks. Each
test waits for the progress line (``--progress on``) to show finished chunks before it strikes.

Disk-full and read-only cases mount a small tmpfs (``mount -t tmpfs``), which needs root; they are skipped
with the reason when mounting is not permitted. (As root, ``chmod 0o555`` does not stop writes, so a
read-only mount is the honest test.)

Outcomes, including the ones marked ``xfail(strict=True)`` (bugs, see their reasons), are tabulated in
docs/robustness.md.
"""

from __future__ import annotations

import fcntl
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import netCDF4
import numpy as np
import pandas as pd
import psutil
import pytest
import xarray as xr

from helpers import run_cli as cli  # the command line in this process (helpers.run_cli)
from helpers import run_cli_in_one_process

N_VARIANTS = 500
CHUNK = 83  # chunk_size() of FAULT_STUDY: 256 MiB / (8 B * 100 001 samples * 4 energies)

FAULT_MODEL = """\
name: fault-model
description: one linear spring and a mass; many history samples so that chunks are small
units: SI
nodes:
  anchor: {position: [0.0], fixed: true}
  body:   {position: [0.1], mass: 2.0}
springs:
  spring:
    nodes: [anchor, body]
    material: {type: linear_elastic, stiffness: 2.0e4}
initial_velocity: {body: [1.0]}
end_time: 2.0
time_step: {safety_factor: 0.9}
output: {interval: 2.0e-5, histories: none}
"""

FAULT_STUDY = """\
name: fault-study
model: models/fault-model.yaml
matrix:
  nodes.body.mass: [1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5]
  springs.spring.material.stiffness: [1.0e4, 1.5e4, 2.0e4, 2.5e4, 3.0e4, 3.5e4, 4.0e4, 4.5e4, 5.0e4, 5.5e4]
  impact_velocity: [1.0, 2.0, 3.0, 4.0, 5.0]
"""

SMALL_STUDY = """\
name: small-study
model: models/fault-model.yaml
matrix:
  nodes.body.mass: [1.0, 2.0]
  impact_velocity: [1.0, 2.0, 3.0]
set: {end_time: 0.05, output: {interval: 1.0e-3, histories: all}}
"""


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


def load(out: Path) -> xr.Dataset:
    with xr.open_dataset(out / "results.nc") as ds:
        return ds.load()


def assert_identical(got: xr.Dataset, ref: xr.Dataset, got_dir: Path, ref_dir: Path) -> None:
    """Every variable and attribute equal (NaN where the reference has NaN), and the same summary.csv."""
    assert set(got.variables) == set(ref.variables)
    for name in ref.variables:
        assert got[name].dims == ref[name].dims, name
        assert got[name].equals(ref[name]), f"{name} differs from the uninterrupted run"
    assert got.attrs == ref.attrs
    a, b = pd.read_csv(got_dir / "summary.csv"), pd.read_csv(ref_dir / "summary.csv")
    pd.testing.assert_frame_equal(a, b, check_exact=True)


def assert_no_complete_result(out: Path) -> None:
    """Nothing that looks like a finished result: no results.nc, no summary.csv; `summary` refuses."""
    assert not (out / "results.nc").exists(), sorted(p.name for p in out.iterdir())
    assert not (out / "summary.csv").exists()
    p = cli("summary", out)
    assert p.returncode != 0 and "Traceback" not in p.stderr
    assert "unfinished" in p.stderr or "no results.nc" in p.stderr, p.stderr


def assert_clean_message(err: str) -> None:
    """An error message a user can read: no traceback, a few lines, an ``error:`` or ``interrupted:`` line."""
    assert "Traceback" not in err, err
    lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip() and "variants/s" not in ln]
    assert 1 <= len(lines) <= 5, lines
    assert any(ln.startswith(("error:", "interrupted:")) for ln in lines), lines


def files_under(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


@pytest.fixture(scope="module")
def fault_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("fault")
    (d / "models").mkdir()
    (d / "models" / "fault-model.yaml").write_text(FAULT_MODEL)
    (d / "study.yaml").write_text(FAULT_STUDY)
    (d / "small.yaml").write_text(SMALL_STUDY)
    return d


@pytest.fixture(scope="module")
def reference(fault_dir: Path) -> tuple[xr.Dataset, Path]:
    """The uninterrupted run: the truth every resumed run must reproduce."""
    out = fault_dir / "reference"
    p = cli("run", fault_dir / "study.yaml", "-o", out, "--progress", "off")
    assert p.returncode == 0, p.stderr
    return load(out), out


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


# ------------------------------------------------------------------------------------------------
# read-only and full output file systems (a small tmpfs)
# ------------------------------------------------------------------------------------------------


def _mount_tmpfs(where: Path, size: str) -> None:
    where.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    p = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)], capture_output=True, text=True
    )
    if p.returncode != 0:
        pytest.skip(f"mount -t tmpfs is not permitted here: {p.stderr.strip()}")


def _remount(where: Path, opts: str) -> None:
    subprocess.run(["mount", "-o", f"remount,{opts}", str(where)], check=True, capture_output=True)


@pytest.fixture
def tmpfs(tmp_path: Path) -> Iterator[Path]:
    where = tmp_path / "tmpfs"
    mounted: list[Path] = []

    def mount(size: str) -> Path:
        _mount_tmpfs(where, size)
        mounted.append(where)
        return where

    yield mount  # type: ignore[misc]
    for m in mounted:
        subprocess.run(["umount", "-l", str(m)], capture_output=True)


def test_read_only_output_folder_is_a_clear_error(fault_dir: Path, tmpfs) -> None:  # type: ignore[no-untyped-def]
    ro = tmpfs("1m")
    (ro / "existing").mkdir()
    _remount(ro, "ro")
    for out, cmd in ((ro / "new", "run"), (ro / "existing", "run"), (ro / "sim", "simulate")):
        target = fault_dir / ("small.yaml" if cmd == "run" else "models/fault-model.yaml")
        p = cli(cmd, target, "-o", out, *(["--progress", "off"] if cmd == "run" else []))
        assert p.returncode != 0, (out, p.stdout)
        assert_clean_message(p.stderr)
        assert re.search(r"Read-only file system|Permission denied|read-only", p.stderr), p.stderr
        assert str(out.name) in p.stderr, p.stderr  # names the path it could not write
    assert files_under(ro) == {"existing"}


def test_output_path_that_is_a_file_or_under_a_file_is_refused(fault_dir: Path, tmp_path: Path) -> None:
    afile = tmp_path / "afile"
    afile.write_text("not a folder\n")
    for out in (afile, afile / "sub"):
        p = cli("run", fault_dir / "small.yaml", "-o", out, "--progress", "off")
        assert p.returncode == 2, p.stderr
        assert_clean_message(p.stderr)
        assert str(afile) in p.stderr
    assert afile.read_text() == "not a folder\n"
    assert files_under(tmp_path) == {"afile"}


@pytest.fixture
def disk_full(fault_dir: Path, tmpfs) -> tuple[Path, subprocess.CompletedProcess[str], Path]:  # type: ignore[no-untyped-def]
    """A run into a 512 KiB tmpfs (the result needs about 1 MB): the netCDF writes fail with ENOSPC."""
    full = tmpfs("512k")
    out = full / "out"
    p = cli("run", fault_dir / "study.yaml", "-o", out, "--progress", "off")
    return full, p, out


def test_disk_full_while_writing_results_leaves_partial_only(disk_full) -> None:  # type: ignore[no-untyped-def]
    full, p, out = disk_full
    assert p.returncode not in (0, 130), p.stdout
    assert sorted(x.name for x in out.iterdir()) == ["results.nc.partial"]
    assert_no_complete_result(out)


def test_disk_full_is_a_clear_message(disk_full) -> None:  # type: ignore[no-untyped-def]
    full, p, out = disk_full
    assert_clean_message(p.stderr)
    assert "No space left" in p.stderr or "disk" in p.stderr, p.stderr


def test_disk_full_then_freed_resume_completes_identically(
    disk_full,
    fault_dir: Path,
    reference: tuple[xr.Dataset, Path],  # type: ignore[no-untyped-def]
) -> None:
    full, p, out = disk_full
    _remount(full, "size=64m")
    r = cli("run", fault_dir / "study.yaml", "-o", out, "--resume", "--progress", "off")
    assert r.returncode == 0, r.stderr[-1500:]
    assert_identical(load(out), reference[0], out, reference[1])


def test_disk_full_while_writing_the_summary_then_resume_completes(
    fault_dir: Path,
    reference: tuple[xr.Dataset, Path],
    tmpfs,  # type: ignore[no-untyped-def]
) -> None:
    """Room for results.nc.partial but not for summary.csv: the run fails before the rename, cleanly."""
    size = (reference[1] / "results.nc").stat().st_size + 128 * 1024
    full = tmpfs(f"{size // 4096 * 4096}")
    out = full / "out"
    p = cli("run", fault_dir / "study.yaml", "-o", out, "--progress", "off")
    assert p.returncode == 1, p.stderr
    assert_clean_message(p.stderr)
    assert "No space left on device" in p.stderr
    assert not (out / "results.nc").exists() and (out / "results.nc.partial").exists()
    assert_no_complete_result(out)
    _remount(full, "size=64m")
    r = cli("run", fault_dir / "study.yaml", "-o", out, "--resume", "--progress", "off")
    assert r.returncode == 0, r.stderr
    assert "(0 variants computed" in r.stdout  # every variant was already in the partial file
    assert sorted(x.name for x in out.iterdir()) == [
        "manifest.json",
        "results.nc",
        "summary.csv",
        "summary.parquet",
    ]
    assert_identical(load(out), reference[0], out, reference[1])


# ------------------------------------------------------------------------------------------------
# paths
# ------------------------------------------------------------------------------------------------


def test_model_path_is_relative_to_the_study_file_not_the_working_directory(tmp_path: Path) -> None:
    proj = tmp_path / "project"
    (proj / "models").mkdir(parents=True)
    (proj / "models" / "fault-model.yaml").write_text(FAULT_MODEL)
    (proj / "small.yaml").write_text(SMALL_STUDY)
    elsewhere = tmp_path / "elsewhere"
    (elsewhere / "models").mkdir(parents=True)
    (elsewhere / "models" / "fault-model.yaml").write_text(
        "name: decoy\nnodes: {}\n"
    )  # invalid if it were read
    for study in ("../project/small.yaml", str(proj / "small.yaml")):
        p = cli("validate", study, cwd=elsewhere)
        assert p.returncode == 0 and "valid study (6 variants)" in p.stdout, p.stderr
    p = cli("run", "../project/small.yaml", "-o", "out", "--progress", "off", cwd=elsewhere)
    assert p.returncode == 0, p.stderr
    ds = load(elsewhere / "out")
    assert Path(ds.attrs["model_file"]).resolve() == (proj / "models" / "fault-model.yaml").resolve()
    assert ds.attrs["model_yaml"] == FAULT_MODEL


def test_output_is_written_only_inside_the_chosen_folder(fault_dir: Path, tmp_path: Path) -> None:
    proj = tmp_path / "project"
    (proj / "models").mkdir(parents=True)
    (proj / "models" / "fault-model.yaml").write_text(FAULT_MODEL)
    (proj / "small.yaml").write_text(SMALL_STUDY)
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    before = files_under(tmp_path)
    steps = [
        ("run", "../project/small.yaml", "-o", "../chosen/run", "--progress", "off"),
        ("simulate", str(proj / "models" / "fault-model.yaml"), "-o", str(tmp_path / "chosen" / "sim")),
        ("run", "../project/small.yaml", "-o", "../chosen/run", "--force", "--progress", "off"),
        ("run", "../project/small.yaml", "--dry-run"),
        ("validate", "../project/small.yaml"),
        ("summary", "../chosen/run"),
    ]
    for argv in steps:
        p = cli(*argv, cwd=cwd)
        assert p.returncode == 0, (argv, p.stderr)
    new = files_under(tmp_path) - before
    assert new and all(f == "chosen" or f.startswith("chosen/") for f in new), sorted(new)
    assert sorted(new) == [
        "chosen",
        "chosen/run",
        "chosen/run/manifest.json",
        "chosen/run/results.nc",
        "chosen/run/summary.csv",
        "chosen/run/summary.parquet",
        "chosen/sim",
        "chosen/sim/manifest.json",
        "chosen/sim/results.nc",
        "chosen/sim/summary.csv",
        "chosen/sim/summary.parquet",
    ]
    # without -o the folder is results/<study name> under the working directory, and nothing else
    p = cli("run", "../project/small.yaml", "--progress", "off", cwd=cwd)
    assert p.returncode == 0, p.stderr
    assert files_under(cwd) == {
        "results",
        "results/small-study",
        "results/small-study/results.nc",
        "results/small-study/summary.csv",
        "results/small-study/summary.parquet",
        "results/small-study/manifest.json",
    }


@pytest.mark.parametrize("name", ["../escape", "a/b", "/abs", ".."])
def test_study_name_cannot_steer_the_default_output_folder(tmp_path: Path, name: str) -> None:
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "fault-model.yaml").write_text(FAULT_MODEL)
    (tmp_path / "s.yaml").write_text(SMALL_STUDY.replace("name: small-study", f"name: '{name}'"))
    (tmp_path / "cwd").mkdir()
    before = files_under(tmp_path)
    p = cli("run", "../s.yaml", "--progress", "off", cwd=tmp_path / "cwd")
    assert p.returncode == 2, p.stderr
    assert "s.yaml:1: name:" in p.stderr
    assert files_under(tmp_path) == before


def test_existing_results_are_not_overwritten_without_force(fault_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    p = cli("run", fault_dir / "small.yaml", "-o", out, "--progress", "off")
    assert p.returncode == 0, p.stderr
    stamp = {f: ((out / f).read_bytes(), (out / f).stat().st_mtime_ns) for f in ("results.nc", "summary.csv")}
    (out / "notes.txt").write_text("mine\n")
    # another study into the same folder: refused, exit 2, nothing touched
    other = fault_dir / "other.yaml"
    other.write_text(SMALL_STUDY.replace("name: small-study", "name: other-study"))
    p = cli("run", other, "-o", out, "--progress", "off")
    assert p.returncode == 2, p.stderr
    assert_clean_message(p.stderr)
    assert "--force" in p.stderr and "other-study" in p.stderr and "small-study" in p.stderr
    for f, (data, mtime) in stamp.items():
        assert (out / f).read_bytes() == data and (out / f).stat().st_mtime_ns == mtime
    # the same study again: its finished variants are reused, the numbers stay identical
    ref = load(out)
    p = cli("run", fault_dir / "small.yaml", "-o", out, "--progress", "off")
    assert p.returncode == 0, p.stderr
    assert "(0 variants computed" in p.stdout, p.stdout
    again = load(out)
    for name in ref.variables:
        assert again[name].equals(ref[name]), name
    # --force recomputes, and removes only its own files
    p = cli("run", other, "-o", out, "--force", "--progress", "off")
    assert p.returncode == 0, p.stderr
    assert load(out).attrs["study_name"] == "other-study"
    assert (out / "notes.txt").read_text() == "mine\n"
    assert sorted(x.name for x in out.iterdir()) == [
        "manifest.json",
        "notes.txt",
        "results.nc",
        "summary.csv",
        "summary.parquet",
    ]


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


# ------------------------------------------------------------------------------------------------
# YAML attacks through the command line
# ------------------------------------------------------------------------------------------------

GOOD_STUDY = "name: attack\nmodel: models/fault-model.yaml\nmatrix:\n  nodes.body.mass: [1.0, 2.0]\n"
LAUGHS = "".join(
    f"{chr(97 + k)}: &{chr(97 + k)} [" + ", ".join(["lol" if k == 0 else f"*{chr(96 + k)}"] * 10) + "]\n"
    for k in range(9)
)  # 10^9 values once expanded


def _model(old: str, new: str) -> str:
    assert old in FAULT_MODEL
    return FAULT_MODEL.replace(old, new, 1)


# (id, which file is attacked, its text, the line and field the message must name)
ATTACKS = [
    (
        "python-object-apply",
        "model",
        _model("end_time: 2.0", "end_time: !!python/object/apply:os.system ['touch PWNED']"),
        12,
        "end_time",
    ),
    ("python-name", "model", _model("mass: 2.0}", "mass: !!python/name:os.system }"), 6, "nodes.body.mass"),
    (
        "python-object-new-in-study",
        "study",
        GOOD_STUDY.replace("[1.0, 2.0]", "[!!python/object/new:subprocess.Popen [['touch', 'PWNED']]]"),
        4,
        "matrix.nodes.body.mass.0",
    ),
    (
        "local-tag",
        "study",
        GOOD_STUDY.replace("[1.0, 2.0]", "!custom [1.0, 2.0]"),
        4,
        "matrix.nodes.body.mass",
    ),
    ("billion-laughs-model", "model", LAUGHS + FAULT_MODEL, 6, ""),
    ("billion-laughs-study", "study", LAUGHS + GOOD_STUDY, 6, ""),
    (
        "deep-flow-nesting",
        "model",
        FAULT_MODEL + "description2: " + "[" * 100_000 + "]" * 100_000 + "\n",
        15,
        "",
    ),
    (
        "deep-block-nesting",
        "study",
        GOOD_STUDY
        + "set:\n"
        + "".join("  " * (k + 1) + f"k{k}:\n" for k in range(200))
        + "  " * 201
        + "v: 1\n",
        69,
        "",
    ),
    (
        "huge-integer",
        "study",
        GOOD_STUDY.replace("[1.0, 2.0]", "[" + "9" * 1_000_000 + "]"),
        4,
        "matrix.nodes.body.mass.0",
    ),
    ("float-overflow-to-inf", "model", _model("mass: 2.0}", "mass: 1.0e400}"), 6, "nodes.body.mass"),
    (
        "nan-in-matrix",
        "study",
        GOOD_STUDY.replace("[1.0, 2.0]", "[1.0, .nan]"),
        4,
        "matrix.nodes.body.mass.1",
    ),
    ("inf-in-set", "study", GOOD_STUDY + "set: {end_time: .inf}\n", 5, "set"),
    (
        "minus-inf-in-model",
        "model",
        _model("stiffness: 2.0e4", "stiffness: -.inf"),
        10,
        "springs.spring.material.stiffness",
    ),
    ("document-over-20-MB", "model", FAULT_MODEL + "# " + "x" * (21 * 2**20) + "\n", None, ""),
]


#: attacks whose regression would hang or fill memory: their commands run in a subprocess with a timeout (the
#: others in this process); all of them in ONE subprocess (:func:`may_hang`), with the variant bomb's run
MAY_HANG = {
    "billion-laughs-model",
    "billion-laughs-study",
    "deep-flow-nesting",
    "deep-block-nesting",
    "huge-integer",
    "document-over-20-MB",
}


def _attack_files(root: Path, kind: str, text: str) -> tuple[Path, list[tuple[str | Path, ...]]]:
    """The attacked file (the model or the study, the other one good) written under ``root``; the commands
    that read it."""
    (root / "models").mkdir(parents=True)
    model = root / "models" / "fault-model.yaml"
    study = root / "study.yaml"
    model.write_text(text if kind == "model" else FAULT_MODEL)
    study.write_text(text if kind == "study" else GOOD_STUDY)
    attacked = _attacked(root, kind)
    commands: list[tuple[str | Path, ...]] = [
        ("validate", attacked),
        ("run", study, "-o", root / "out", "--progress", "off"),
    ]
    if kind == "model":
        commands.append(("simulate", model, "-o", root / "out"))
    return attacked, commands


def _attacked(root: Path, kind: str) -> Path:
    return root / "models" / "fault-model.yaml" if kind == "model" else root / "study.yaml"


def _bomb_study(folder: Path) -> Path:
    """A study of 100 values on each of six axes: 10^12 variants."""
    values = "[" + ", ".join(f"{1.0 + k / 100:.2f}" for k in range(100)) + "]"
    axes = [
        "nodes.body.mass",
        "springs.spring.material.stiffness",
        "impact_velocity",
        "end_time",
        "nodes.body.position.0",
        "initial_velocity.body.0",
    ]
    study = folder / "bomb.yaml"
    study.write_text(
        "name: bomb\nmodel: models/fault-model.yaml\nmatrix:\n" + "".join(f"  {a}: {values}\n" for a in axes)
    )
    return study


@pytest.fixture(scope="module")
def may_hang(
    fault_dir: Path, tmp_path_factory: pytest.TempPathFactory
) -> dict[str, tuple[Path, list[tuple[str | Path, ...]], list[subprocess.CompletedProcess[str]]]]:
    """Every command whose regression would hang or fill memory (the MAY_HANG attacks' and the variant
    bomb's run), one after the other in ONE subprocess that must end within 240 s (a hang fails these tests
    at the timeout, a blow-up ends that process and not the test run) in a folder that holds a folder per
    case: one interpreter start instead of seven. {case id: (its folder, its commands, what each did)}."""
    here = tmp_path_factory.mktemp("may-hang")
    cases: dict[str, tuple[Path, list[tuple[str | Path, ...]]]] = {}
    for case, kind, text, _, _ in ATTACKS:
        if case in MAY_HANG:
            cases[case] = (here / case, _attack_files(here / case, kind, text)[1])
    (here / "bomb").mkdir()
    cases["bomb"] = (
        here / "bomb",
        [("run", _bomb_study(fault_dir), "-o", here / "bomb" / "out", "--progress", "off")],
    )
    done = iter(
        run_cli_in_one_process(*[c for _, cmds in cases.values() for c in cmds], cwd=here, timeout=240)
    )
    return {case: (root, cmds, [next(done) for _ in cmds]) for case, (root, cmds) in cases.items()}


@pytest.mark.parametrize(
    ("kind", "text", "line", "field"), [a[1:] for a in ATTACKS], ids=[a[0] for a in ATTACKS]
)
def test_yaml_attack_is_refused_with_exit_2(
    tmp_path: Path, kind: str, text: str, line: int | None, field: str, request: pytest.FixtureRequest
) -> None:
    case = request.node.callspec.id
    if case in MAY_HANG:  # run in the module's one subprocess with a timeout (its working folder: the parent)
        tmp_path, commands, done = request.getfixturevalue("may_hang")[case]
        attacked = _attacked(tmp_path, kind)
        assert not (tmp_path.parent / "PWNED").exists()
    else:
        attacked, commands = _attack_files(tmp_path, kind, text)
        done = [cli(*argv, cwd=tmp_path) for argv in commands]
    for argv, p in zip(commands, done, strict=True):
        assert p.returncode == 2, (argv, p.stdout, p.stderr[-1500:])
        assert "Traceback" not in p.stderr
        lines = p.stderr.splitlines()
        assert lines[0] == "error: invalid input" and len(lines) < 40, p.stderr[:2000]
        where = f"{attacked}:{line}:" if line is not None else f"{attacked}:"
        head = where + (f" {field}:" if field else "")
        assert any(ln.startswith(head) for ln in lines[1:]), (head, p.stderr[:2000])
    assert not (tmp_path / "PWNED").exists()
    assert not (tmp_path / "out").exists()


def test_variant_bomb_is_refused_without_traceback(fault_dir: Path, may_hang: dict[str, Any]) -> None:
    study = _bomb_study(fault_dir)
    p = cli("run", study, "--dry-run")  # refused up front, naming the count and the limit
    assert p.returncode == 2 and "1,000,000,000,000 variants" in p.stderr, p.stderr
    assert_clean_message(p.stderr)
    folder, _, (p,) = may_hang["bomb"]  # the run itself, in the module's one subprocess with a timeout
    out = folder / "out"
    assert p.returncode in (1, 2), p.stderr[-1500:]
    assert_clean_message(p.stderr)
    assert not out.exists() or not any(out.iterdir())
