"""summary.parquet made from the chunks as they are written (results/summary_stream.py, issue 25).

Truth: the table :func:`crashstudy.results.tables.write_summary` makes from the finished store (what every
run wrote before): the streamed file must be the same bytes. A 1-D mass on a spring (k = 10^6 N/m, fixed
dt 0.12 ms): the masses under 3.6 g have dt_crit = 2 sqrt(m / k) below dt and fail (NaN rows, a failure
text each), the others peak at v0 sqrt(k m) sin(t sqrt(k / m)) (checked, rel 5e-3: 8 steps). 6 masses x 4 speeds in
chunks of 5 and row groups of 7 (monkeypatched SUMMARY_BLOCK): row groups span chunks, the last is short.
NumPy reference kernel (no compile).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import crashstudy.results.store as store
import crashstudy.results.tables as tables
from crashstudy import open_results
from crashstudy.results.reader import open_raw
from crashstudy.run.runner import run_plan
from crashstudy.study.plan import load_study

MASSES = [0.001, 0.002, 1.0, 2.0, 3.0, 4.0]  # fastest axis: the first row group holds every failure text
SPEEDS = [0.5, 1.0, 1.5, 2.0]
K, DT, END = 1.0e6, 1.2e-4, 9.6e-4  # 8 steps; m >= 1 kg: dt <= T / 52, still rising at END
MODEL = {
    "name": "st",
    "units": "SI",
    "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
    "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": K}}},
    "initial_velocity": {"b": [1.0]},
    "end_time": END,
    "time_step": {"dt": DT},
    "output": {"interval": END, "histories": "none"},
}


def _plan(tmp: Path, axes: dict[str, list[float]]):  # type: ignore[no-untyped-def]
    (tmp / "model.yaml").write_text(yaml.safe_dump(MODEL, sort_keys=False))
    study = {"name": "stream", "model": "model.yaml", "matrix": axes}
    (tmp / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    return load_study(tmp / "study.yaml")


@pytest.fixture
def made(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Row groups of 7 rows; records how each run made its summary (``stream`` or ``store``)."""
    monkeypatch.setattr(tables, "SUMMARY_BLOCK", 7)
    how: list[str] = []
    real = store.write_summary

    def from_store(*a, **k):  # type: ignore[no-untyped-def]
        how.append("store")
        return real(*a, **k)

    monkeypatch.setattr(store, "write_summary", from_store)
    return how


def _from_store(out: Path, name: str, table: str = tables.PARQUET) -> bytes:
    """The table write_summary makes from the finished store in ``out`` (written beside, then read)."""
    scratch = out.parent / f"scratch-{out.name}-{table}"
    scratch.mkdir()
    with open_raw(out / name) as ds:
        tables.write_summary(ds, scratch, table == tables.SUMMARY)
    return (scratch / table).read_bytes()


@pytest.mark.parametrize("kind", ["netcdf", "zarr"])
def test_a_streamed_summary_is_the_table_made_from_the_store_byte_for_byte(
    tmp_path: Path, made: list[str], kind: str
) -> None:
    plan = _plan(tmp_path, {"impact_velocity": SPEEDS, "nodes.b.mass": MASSES})
    run_plan(plan, tmp_path / "R", kernel="reference", chunk=5, progress=False, store=kind, csv=False)
    assert made == []  # streamed: the store was not read back
    name = "results.nc" if kind == "netcdf" else "results.zarr"
    assert (tmp_path / "R" / tables.PARQUET).read_bytes() == _from_store(tmp_path / "R", name)
    s = open_results(tmp_path / "R").summary
    m, v0 = s["nodes.b.mass"].to_numpy(), s["impact_velocity"].to_numpy()
    bad = 2 * np.sqrt(m / K) < DT
    assert bad.sum() == 2 * len(SPEEDS) and (s["status"][bad] == "failed").all()
    assert (
        np.isnan(s["peak_force.s"][bad]).all()
        and s["failure_reason"][bad].str.contains("above the critical").all()
    )
    want = v0[~bad] * np.sqrt(K * m[~bad]) * np.sin(END * np.sqrt(K / m[~bad]))
    np.testing.assert_allclose(s["peak_force.s"].to_numpy()[~bad], want, rtol=5e-3)  # 8 steps: 0.22 % at 1 kg


def test_a_streamed_summary_csv_is_the_table_made_from_the_store_byte_for_byte(
    tmp_path: Path, made: list[str]
) -> None:
    # summary.csv asked for (what a study of up to CSV_MAX variants writes by default): streamed beside the
    # Parquet table, through the same columns and pyarrow's CSV writer, not read back from the store
    plan = _plan(tmp_path, {"impact_velocity": SPEEDS, "nodes.b.mass": MASSES})
    run_plan(plan, tmp_path / "R", kernel="reference", chunk=5, progress=False, csv=True)
    assert made == []
    for table in (tables.PARQUET, tables.SUMMARY):
        assert (tmp_path / "R" / table).read_bytes() == _from_store(tmp_path / "R", "results.nc", table), (
            table
        )
    # the manifest's SHA-256 of each, hashed as the stream wrote it: that of the file's bytes
    files = json.loads((tmp_path / "R" / "manifest.json").read_text())["files"]
    for table in (tables.PARQUET, tables.SUMMARY):
        assert files[table]["sha256"] == hashlib.sha256((tmp_path / "R" / table).read_bytes()).hexdigest()
    text = (tmp_path / "R" / tables.SUMMARY).read_text().splitlines()
    assert len(text) == 1 + len(MASSES) * len(SPEEDS) and text[0].startswith('"variant"')
    assert sum('"failed"' in line for line in text) == 2 * len(SPEEDS)  # the 1 and 2 g masses


def test_a_text_first_seen_after_a_written_row_group_makes_the_table_from_the_store(
    tmp_path: Path, made: list[str]
) -> None:
    # the masses the slow axis, the failing ones (1 and 2 g) last: their failure texts first appear after
    # the first row group was written
    plan = _plan(tmp_path, {"nodes.b.mass": MASSES[::-1], "impact_velocity": SPEEDS})
    run_plan(plan, tmp_path / "R", kernel="reference", chunk=5, progress=False, csv=False)
    assert made == ["store"]
    assert not list((tmp_path / "R").glob("*.partial"))  # the dropped stream left nothing behind
    assert (tmp_path / "R" / tables.PARQUET).read_bytes() == _from_store(tmp_path / "R", "results.nc")


def test_a_resumed_run_made_from_the_store_equals_a_streamed_run_byte_for_byte(
    tmp_path: Path, made: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    plan = _plan(tmp_path, {"impact_velocity": SPEEDS, "nodes.b.mass": MASSES})
    run_plan(plan, tmp_path / "fresh", kernel="reference", chunk=5, progress=False, csv=False)
    assert made == []
    real, calls = store.ResultWriter.write, []

    def write(self, res):  # type: ignore[no-untyped-def]
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(self, res)

    monkeypatch.setattr(store.ResultWriter, "write", write)
    with pytest.raises(KeyboardInterrupt):
        run_plan(plan, tmp_path / "R", kernel="reference", chunk=5, progress=False, csv=False)
    monkeypatch.setattr(store.ResultWriter, "write", real)
    run_plan(plan, tmp_path / "R", kernel="reference", chunk=5, progress=False, resume=True, csv=False)
    assert made == ["store"]
    assert (tmp_path / "R" / tables.PARQUET).read_bytes() == (
        tmp_path / "fresh" / tables.PARQUET
    ).read_bytes()
