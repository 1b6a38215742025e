"""The HDF5 chunk layout of results.nc along ``variant`` (issue 25: the CPU of writing a chunk).

Each chunk a run writes is whole HDF5 chunks: the store's chunk length along ``variant`` is the run's
chunk (halved while one HDF5 chunk would exceed ``store.CHUNK_BYTES``), 4096 when the run's chunk is
smaller; the values read back are the ones written whatever the layout (the run's numbers, compared
with the reference kernel's batch written through a 4096 layout)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import netCDF4
import pandas as pd
import pytest
import xarray as xr

from crashstudy.results import store
from crashstudy.run import runner
from crashstudy.study.plan import load_study

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from scale import write_study  # noqa: E402 - the 2-spring study of the scale benchmark (n / 100 x 100 masses)


@pytest.mark.parametrize(("chunk", "want"), [(8192, 8192), (1000, 4096), (5001, 5001)])
def test_variant_chunk_is_the_runs_chunk_within_the_byte_bound(tmp_path: Path, chunk: int, want: int) -> None:
    """The run's chunk (odd or not), 4096 below it; a (variant, spring) variable the same (16 B rows);
    the byte bound (halving) itself: ``_cv`` of a 2^20-variant chunk, 1 and 64 values wide."""
    plan = load_study(write_study(tmp_path, 10_000))
    w = store.ResultWriter(tmp_path / "out", plan, chunk=chunk)
    try:
        got = w.nc.variables["dt"].chunking()[0]
        assert got == min(want, 10_000)
        pf = w.nc.variables["peak_force"].chunking()
        assert pf[0] * pf[1] * 8 <= store.CHUNK_BYTES and pf[0] == min(
            10_000, want if chunk < 2**20 else 2**16
        )
    finally:
        w.abort()


def test_values_are_the_same_under_the_old_layout(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A run with chunks of 8192 variants and the same run written with the 4096 layout (``_cv`` fixed at
    4096): results.nc identical (xarray) and summary.parquet equal (pandas)."""
    study = write_study(tmp_path, 10_000)
    runner.run_plan(load_study(study), tmp_path / "a", kernel="reference", chunk=8192, progress=False)
    monkeypatch.setattr(store.ResultWriter, "_cv", lambda self, width: min(4096, self.plan.n_variants))
    runner.run_plan(load_study(study), tmp_path / "b", kernel="reference", chunk=8192, progress=False)
    assert netCDF4.Dataset(tmp_path / "a" / "results.nc").variables["dt"].chunking() == [8192]
    assert netCDF4.Dataset(tmp_path / "b" / "results.nc").variables["dt"].chunking() == [4096]
    with (
        xr.open_dataset(tmp_path / "a" / "results.nc") as a,
        xr.open_dataset(tmp_path / "b" / "results.nc") as b,
    ):
        assert a.identical(b)
    pa_: Any = pd.read_parquet(tmp_path / "a" / "summary.parquet")
    assert pa_.equals(pd.read_parquet(tmp_path / "b" / "summary.parquet"))
