"""Faults, with real files: a read-only or full output file system (issue 5, item 4).

Disk-full and read-only cases mount a small tmpfs (``mount -t tmpfs``), which needs root; they are skipped
with the reason when mounting is not permitted. (As root, ``chmod 0o555`` does not stop writes, so a
read-only mount is the honest test.)

The contract under test (docs/studies.md, issue 5) and the shared fault study are described in
fault_runs.py."""

from __future__ import annotations

import os
import re
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
import xarray as xr

from fault_runs import (
    assert_clean_message,
    assert_identical,
    assert_no_complete_result,
    files_under,
    load,
)
from helpers import run_cli as cli  # the command line in this process (helpers.run_cli)

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
