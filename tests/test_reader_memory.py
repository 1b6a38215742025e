"""Issue 19, the reading side at scale: the manifest hash once per Results object (without a hole),
``compare``, ``open_results(...).summary`` and ``.dataset`` in bounded memory. Small N (the large sizes
live in benchmarks/scale.py); the row groups are made small so that a few 10^3 variants show the trend."""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import pytest

from crashstudy.errors import InputError
from crashstudy.results import integrity, tables
from crashstudy.results.reader import open_results
from crashstudy.run import runner
from crashstudy.study.plan import load_study

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from scale import write_study  # noqa: E402 - the 2-spring study of the scale benchmark (n / 100 x 100 masses)

BLOCK = 256  # rows per Parquet row group in these tests


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> dict[int, Path]:
    """Finished 2-spring results at N = 1000 and 4N variants (reference kernel), row groups of BLOCK rows."""
    root = tmp_path_factory.mktemp("reader-memory")
    out = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(tables, "SUMMARY_BLOCK", BLOCK)
        for size in (1000, 4000):
            study = write_study(root / str(size), size)
            out[size] = root / str(size) / "out"
            runner.run_plan(load_study(study), out[size], kernel="reference", chunk=4096, progress=False)
    return out


# --- the manifest hash, once per Results object --------------------------------------------------------


@pytest.fixture
def hashes(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts the SHA-256 passes over a file (each appends the bytes it hashed)."""
    seen: list[int] = []
    real = integrity.sha256_of

    def counting(fh: object, *a: object, **k: object) -> str:
        seen.append(os.fstat(fh.fileno()).st_size)  # type: ignore[attr-defined]
        return real(fh, *a, **k)  # type: ignore[arg-type]

    monkeypatch.setattr(integrity, "sha256_of", counting)
    return seen


def test_a_results_object_hashes_its_summary_once_however_often_it_reads_it(
        results: dict[int, Path], hashes: list[int]) -> None:  # fmt: skip
    """Names, row count, a column peak, one row, the blocks and the whole table: six reads, one hash
    (before: one per read, 6 x 12 GB at 10^8 variants)."""
    res = open_results(results[1000])
    assert res.summary_rows() == 1000 and "status" in res.summary_names()
    peak = res.column_peak("peak_force.s2")
    assert res.summary_row(7)["variant"].tolist() == [7]
    assert sum(len(b) for b in res.summary_batches(["status"])) == 1000
    assert peak is not None and res.summary_columns(["peak_force.s2"])["peak_force.s2"].max() == peak[0]
    assert hashes == [(results[1000] / "summary.parquet").stat().st_size]
    res.close()
    open_results(results[1000]).summary_rows()  # another object hashes again
    assert len(hashes) == 2


def test_a_results_object_dropped_without_close_releases_the_file_it_holds(results: dict[int, Path]) -> None:
    import gc
    import warnings

    res = open_results(results[1000])
    assert res.summary_rows() == 1000  # hashed: its handle held open
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        del res
        gc.collect()
    assert not [w for w in seen if issubclass(w.category, ResourceWarning)], [str(w.message) for w in seen]


def _edited_copy(folder: Path, dest: Path) -> Path:
    """summary.parquet of ``folder`` with one byte of a stored number flipped (same size)."""
    raw = bytearray((folder / "summary.parquet").read_bytes())
    raw[len(raw) // 3] ^= 0x01
    dest.write_bytes(bytes(raw))
    return dest


@pytest.mark.parametrize("how", ["renamed over", "edited in place, times put back"])
def test_a_summary_changed_after_its_hash_is_still_refused(results: dict[int, Path], tmp_path: Path,
                                                           hashes: list[int], how: str) -> None:  # fmt: skip
    folder = shutil.copytree(results[1000], tmp_path / "r")
    res = open_results(folder)
    assert res.summary_rows() == 1000  # hashed and vouched for
    target = folder / "summary.parquet"
    if how == "renamed over":
        os.replace(_edited_copy(folder, tmp_path / "edited.parquet"), target)
    else:  # same inode, same size; mtime set back to the hashed one: only ctime tells
        st = target.stat()
        edited = _edited_copy(folder, tmp_path / "edited.parquet").read_bytes()
        with open(target, "r+b") as fh:
            fh.write(edited)
        os.utime(target, ns=(st.st_atime_ns, st.st_mtime_ns))
    with pytest.raises(InputError, match="SHA-256 of summary.parquet"):
        res.summary_rows()
    assert len(hashes) == 2
    res.close()


# --- open_results(...).summary and .dataset of a result too large to hold --------------------------------


def test_summary_is_whole_up_to_its_limit_and_refused_beyond_with_the_bounded_readers_named(
        results: dict[int, Path], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    import pandas as pd

    from crashstudy.cli.main import main
    from crashstudy.results import reader

    folder = results[1000]
    res = open_results(folder)
    res.summary_limit = 1000
    pd.testing.assert_frame_equal(res.summary, pd.read_parquet(folder / "summary.parquet"))
    res.summary_limit = 999
    with pytest.raises(InputError, match=r"1000 rows, more than the 999 .*\.summary_batches\(columns, rows\)"):
        _ = res.summary
    res.summary_limit = None
    assert len(res.summary) == 1000
    monkeypatch.setattr(reader, "SUMMARY_ROWS_MAX", 999)  # a command that needs the whole table: exit 2
    capsys.readouterr()
    assert main(["report", str(folder), "-o", str(folder.parent / "report.html")]) == 2
    err = capsys.readouterr().err
    assert "summary.parquet" in err and ".summary_batches" in err and "Traceback" not in err, err


def _opened_peak(folder: Path) -> tuple[int, object]:
    """Traced peak bytes of opening ``folder``'s dataset (the object is kept open for the caller)."""
    import tracemalloc

    res = open_results(folder)
    res.summary_rows()  # the manifest hash: not what is measured
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        _ = res.dataset
        return tracemalloc.get_traced_memory()[1], res
    finally:
        tracemalloc.stop()


def test_a_large_dataset_opens_without_reading_its_variables_and_reads_what_the_eager_one_reads(
        results: dict[int, Path], monkeypatch: pytest.MonkeyPatch) -> None:  # fmt: skip
    """Beyond summary_limit variants: every variable along ``variant`` is lazy after opening, the traced
    peak of opening grows < 1 B per variant (N -> 4N; the eager open decodes the texts whole: >= 24 B),
    and indexed slices equal the eager dataset's (the independent truth: decode_texts of the whole)."""
    import numpy as np

    from crashstudy.results import reader

    eager = open_results(results[4000]).dataset
    monkeypatch.setattr(reader, "SUMMARY_ROWS_MAX", 100, raising=False)
    peaks = {n: _opened_peak(results[n]) for n in (1000, 4000)}
    assert peaks[4000][0] - peaks[1000][0] < 3000 * 1 + 64 * 1024, {n: p for n, (p, _) in peaks.items()}
    lazy = peaks[4000][1].dataset  # type: ignore[attr-defined]
    along = [n for n, v in lazy.variables.items() if "variant" in v.dims]
    assert "status" in along and "failure_reason" in along and "peak_force" in along
    assert not [n for n in along if isinstance(lazy[n].variable._data, np.ndarray)]
    for name in along:
        for part in (slice(5, 50), slice(3990, None), [0, 17, 3999]):
            np.testing.assert_array_equal(lazy[name].isel(variant=part).values,
                                          eager[name].isel(variant=part).values)  # fmt: skip


# --- the store's template: the variant numbers written in blocks -----------------------------------------


@pytest.mark.parametrize("store_kind", ["netcdf", "zarr"])
def test_creating_a_store_does_not_hold_every_variant_number(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             store_kind: str) -> None:  # fmt: skip
    """The traced peak of creating the result store (template: variant numbers, axis values) grows < 2 B
    per variant from 1e5 to 4e5 variants, blocks of 4096 (np.arange of the whole study: 8 B per variant,
    800 MB at 10^8; independent truth: the stored numbers are 0 .. N-1)."""
    import tracemalloc

    import numpy as np

    from crashstudy.results import store

    monkeypatch.setattr(store, "AXIS_BLOCK", 4096)
    peaks = {}
    for n in (100_000, 400_000):
        plan = load_study(write_study(tmp_path / str(n), n))
        tracemalloc.start()
        try:
            tracemalloc.reset_peak()
            writer = store.ResultWriter(tmp_path / str(n) / "out", plan, store=store_kind, chunk=65536)
            peaks[n] = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
        numbers = writer.nc.variables["variant"][:]
        np.testing.assert_array_equal(numbers, np.arange(n))
        writer.abort()
    assert peaks[400_000] - peaks[100_000] < 300_000 * 2 + 256 * 1024, peaks
