"""Issue 19, the reading side at scale: the manifest hash once per Results object (without a hole),
``open_results(...).summary`` and ``.dataset``, ``sensitivity --method correlation`` and ``compare`` in
bounded memory (``compare`` read block by block prints what the whole-table one prints). Small N (the large sizes
live in benchmarks/scale.py); the row groups are made small so that a few 10^3 variants show the trend."""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from crashstudy.analysis import compare_inputs
from crashstudy.analysis.compare import compare
from crashstudy.errors import InputError
from crashstudy.results import integrity, reader, tables
from crashstudy.results.reader import open_results
from crashstudy.run import runner
from crashstudy.study.plan import load_study
from helpers import reseal

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
    results: dict[int, Path], hashes: list[int]
) -> None:
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
def test_a_summary_changed_after_its_hash_is_still_refused(
    results: dict[int, Path], tmp_path: Path, hashes: list[int], how: str
) -> None:
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
    results: dict[int, Path], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import pandas as pd

    from crashstudy.cli.main import main
    from crashstudy.results import reader

    folder = results[1000]
    res = open_results(folder)
    res.summary_limit = 1000
    pd.testing.assert_frame_equal(res.summary, pd.read_parquet(folder / "summary.parquet"))
    res.summary_limit = 999
    with pytest.raises(
        InputError, match=r"1000 rows, more than the 999 .*\.summary_batches\(columns, rows\)"
    ):
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
    results: dict[int, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
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
            np.testing.assert_array_equal(
                lazy[name].isel(variant=part).values, eager[name].isel(variant=part).values
            )


# --- the store's template: the variant numbers written in blocks -----------------------------------------


@pytest.mark.parametrize("store_kind", ["netcdf", "zarr"])
def test_creating_a_store_does_not_hold_every_variant_number(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, store_kind: str
) -> None:
    """The traced peak of creating the result store (template: variant numbers, axis values) grows < 2 B
    per variant (+ 1 MiB) from 1e5 to 4e5 variants, blocks of 16384 (np.arange of the whole study: 8 B per
    variant, 800 MB at 10^8; independent truth: the stored numbers are 0 .. N-1). Measured 2026-11-27:
    growth 4-21 kB with blocks of 16384 (7-150 kB with 4096, which wrote each 65536-variant Zarr chunk 16
    times: 2x the CPU); with AXIS_BLOCK above the study (the whole np.arange at once) the test fails."""
    import gc
    import tracemalloc

    import numpy as np

    from crashstudy.results import store

    monkeypatch.setattr(store, "AXIS_BLOCK", 16384)
    warm_plan = load_study(write_study(tmp_path / "warm", 1000))
    warm = store.ResultWriter(tmp_path / "warm" / "out", warm_plan, store=store_kind, chunk=65536)
    warm.abort()  # the store library's one-time set-up (codecs, caches) stays out of the measured peaks
    peaks = {}
    for n in (100_000, 400_000):
        plan = load_study(write_study(tmp_path / str(n), n))
        gc.collect()  # what earlier tests left to the collector is not freed inside the measured window
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
    # 2 B per variant plus 1 MiB: holding every variant number (8 B) grows 2.4 MB over these 300,000 variants
    # (one suite run saw 1.07 MB of growth from the store library's own state with a 256 KiB allowance)
    assert peaks[400_000] - peaks[100_000] < 300_000 * 2 + 1024 * 1024, peaks


# --- sensitivity --method correlation, block by block ------------------------------------------------------


def _warm_call(argv: list[str]) -> None:
    """The command line ``argv`` once in this process, untraced: the imports and caches of a first call
    stay out of the measured peak (tracemalloc makes this code ~4x slower)."""
    import contextlib
    import io

    from crashstudy.cli.main import main

    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert main(argv) == 0


def _command_peak(argv: list[str]) -> int:
    """Peak bytes of the command line ``argv`` in this process: traced (Python, NumPy) plus the peak of
    pyarrow's memory pool (which tracemalloc does not see)."""
    import contextlib
    import io
    import tracemalloc

    from crashstudy.cli.main import main

    pool, before = pa.proxy_memory_pool(pa.default_memory_pool()), pa.default_memory_pool()
    pa.set_memory_pool(pool)
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            assert main(argv) == 0
        return tracemalloc.get_traced_memory()[1] + pool.max_memory()
    finally:
        tracemalloc.stop()
        pa.set_memory_pool(before)


def test_sensitivity_correlation_reads_block_by_block_and_equals_scipy(
    results: dict[int, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``sensitivity --method correlation`` on N = 1000 and 4N variants, blocks of BLOCK rows, the metric ranked
    in buckets of BLOCK rows: the peak grows < 8 B per variant of the 3N more (+ 128 KiB); measured 1.5; before,
    the five columns whole plus SciPy's ranks: 136 B per variant. The numbers equal scipy.stats.spearmanr / pearsonr
    on the whole columns (1e-12)."""
    from scipy import stats

    from crashstudy.analysis import correlation

    monkeypatch.setattr(reader, "READ_BLOCK", BLOCK)
    monkeypatch.setattr(correlation, "BUCKET_ROWS", BLOCK, raising=False)
    peaks = {}
    for n in (1000, 4000):
        folder = shutil.copytree(results[n], tmp_path / str(n))  # sensitivity.csv is written into the folder
        argv = ["sensitivity", str(folder), "--metric", "peak_force.s2"]
        if n == 1000:
            _warm_call(argv)  # warm: imports and caches of the first call (of the process, not of a folder)
        peaks[n] = _command_peak(argv)
    assert peaks[4000] - peaks[1000] < 3000 * 8 + 128 * 1024, peaks
    got = pd.read_csv(tmp_path / "4000" / "sensitivity.csv").set_index(["axis", "index"])
    whole = pd.read_parquet(results[4000] / "summary.parquet")
    ok = (whole["status"] == "ok").to_numpy() & np.isfinite(whole["peak_force.s2"].to_numpy())
    assert ok.all()
    for axis in ("nodes.m2.mass", "nodes.m1.mass"):
        x, y = whole[axis], whole["peak_force.s2"]
        assert got.loc[(axis, "spearman"), "value"] == pytest.approx(stats.spearmanr(x, y)[0], abs=1e-12)
        assert got.loc[(axis, "pearson"), "value"] == pytest.approx(stats.pearsonr(x, y)[0], abs=1e-12)


# --- compare of large results block by block (analysis/compare_stream.py) ----------------------------------


@pytest.fixture(scope="module")
def moved(results: dict[int, Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Copies of the 1000-variant result with another summary.parquet (resealed): "moved", whose summary moved
    (a metric by 1e-3, past tolerance, and by 1e-9, within; NaN against numbers in two columns: ties of
    infinite score; status changes both ways; row groups of 300 rows, so that the two tables' blocks do not
    line up), its "baseline" (two variants failed), "reversed" (the original rows in reverse order) and
    "subset" (130 of the original rows left out: a damaged folder, said so by either comparison)."""
    root = tmp_path_factory.mktemp("compare-stream")
    original = pd.read_parquet(results[1000] / "summary.parquet")
    df = original.copy()
    df.loc[10:60, "peak_force.s2"] *= 1.0 + 1e-3
    df.loc[100:400, "t_end"] *= 1.0 + 1e-9
    df.loc[[7, 300, 301, 900], "peak_force.s1"] = np.nan
    df.loc[[300, 555], "max_crush.s2"] = np.nan
    status = df["status"].astype(str).to_numpy()
    reason = df["failure_reason"].astype(object).fillna("").astype(str).to_numpy()
    status[[5, 250, 251, 999]], reason[[5, 250, 251, 999]] = "failed", "crushed to zero length"
    df["status"], df["failure_reason"] = pd.Categorical(status), pd.Categorical(reason)
    baseline = original.copy()
    baseline.loc[[250, 600], "status"] = "failed"  # failed -> ok in "moved" at 600, failed -> failed at 250
    return {
        "1000": results[1000],
        "4000": results[4000],
        "moved": _with_summary(results[1000], root / "moved", df, 300),
        "baseline": _with_summary(results[1000], root / "baseline", baseline, BLOCK),
        "reversed": _with_summary(results[1000], root / "reversed", original.iloc[::-1], BLOCK),
        "subset": _with_summary(
            results[1000], root / "subset", original.drop(index=[*range(100, 180), *range(900, 950)]), BLOCK
        ),
    }


def _with_summary(folder: Path, dest: Path, df: pd.DataFrame, rows: int) -> Path:
    """A copy of the result ``folder`` whose summary.parquet is ``df`` (row groups of ``rows``), resealed."""
    shutil.copytree(folder, dest)
    pq.write_table(
        pa.Table.from_pandas(df.reset_index(drop=True), preserve_index=False),
        dest / "summary.parquet",
        row_group_size=rows,
    )
    reseal(dest)
    return dest


def _everything(new: Path, base: Path) -> tuple[object, str, bytes]:
    """(the comparison, its report, its JUnit XML) of ``new`` against ``base``."""
    import xml.etree.ElementTree as ET

    cmp = compare(new, base)
    return cmp, cmp.report(), ET.tostring(cmp.to_junit().getroot())


def test_streamed_compare_prints_and_writes_what_the_whole_table_compare_does(
    moved: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Independent truth: the whole-table comparison (outer merge on the axis values) of the same two folders.
    Streamed (WHOLE_ROWS 100, blocks of BLOCK rows against row groups of 300): the same report, JUnit XML,
    counts, per-metric table and top rows; no per-variant arrays."""
    whole, w_text, w_xml = _everything(moved["moved"], moved["baseline"])
    assert not whole.streamed and len(whole.matched) == 1000  # type: ignore[attr-defined]
    monkeypatch.setattr(compare_inputs, "WHOLE_ROWS", 100)
    monkeypatch.setattr(reader, "READ_BLOCK", BLOCK)
    part, p_text, p_xml = _everything(moved["moved"], moved["baseline"])
    assert part.streamed and part.columns == {} and len(part.matched) == 0  # type: ignore[attr-defined]
    assert p_text == w_text
    assert p_xml == w_xml
    assert "FAILED" in w_text and "status changes (4)" in w_text and "NaN on the other" in w_text
    for cmp in (whole, part):
        assert cmp.failed == whole.failed > 51 and cmp.n_matched == 1000  # type: ignore[attr-defined]
    pd.testing.assert_frame_equal(part.by_metric(), whole.by_metric())  # type: ignore[attr-defined]
    pd.testing.assert_frame_equal(part.top(100), whole.top(100))  # type: ignore[attr-defined]
    pd.testing.assert_frame_equal(part.status, whole.status)  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match="block by block"):
        _ = part.frame  # type: ignore[attr-defined]


@pytest.mark.parametrize("pair", [("moved", "reversed"), ("moved", "subset"), ("subset", "reversed")])
def test_another_order_beyond_the_limit_is_matched_in_hash_parts_as_the_whole_merge_matches_it(
    moved: dict[str, Path], monkeypatch: pytest.MonkeyPatch, pair: tuple[str, str]
) -> None:
    """Another row order or other variants (a baseline in reverse order; 130 variants absent from a side):
    up to the Results objects' summary_limit the tables are merged whole; beyond it (limit 500 rows) they
    are split by a hash of their axis values into parts of ~200 rows, each merged whole. Independent truth:
    the whole merge of the same folders. The same report and JUnit XML (missing and new variants listed)."""
    import xml.etree.ElementTree as ET

    from crashstudy.analysis import compare_match

    whole = compare(moved[pair[0]], moved[pair[1]])
    assert not whole.streamed and (whole.n_missing or whole.n_extra or pair[1] == "reversed")
    monkeypatch.setattr(compare_inputs, "WHOLE_ROWS", 100)
    monkeypatch.setattr(compare_match, "PART_ROWS", 200)
    monkeypatch.setattr(reader, "READ_BLOCK", BLOCK)
    parts: list[Path] = []
    real = compare_match._read
    monkeypatch.setattr(compare_match, "_read", lambda path, *a: parts.append(path) or real(path, *a))
    new, base = open_results(moved[pair[0]]), open_results(moved[pair[1]])
    new.summary_limit = base.summary_limit = 500
    part = compare(new, base)
    assert part.streamed and part.columns == {} and len(parts) == 2 * 5  # 5 parts a side
    assert part.report() == whole.report()
    assert ET.tostring(part.to_junit().getroot()) == ET.tostring(whole.to_junit().getroot())
    pd.testing.assert_frame_equal(part.top(100), whole.top(100))
    pd.testing.assert_frame_equal(part.by_metric(), whole.by_metric())
    for key in ("status", "missing", "extra"):
        got, want = getattr(part, key), getattr(whole, key)
        assert len(got) == len(want)
        if len(want):
            pd.testing.assert_frame_equal(got, want, check_dtype=False)
    new.close()
    base.close()


@pytest.mark.parametrize("order", ["same", "reversed"])
def test_compare_of_a_large_result_does_not_grow_with_the_variants(
    moved: dict[str, Path], monkeypatch: pytest.MonkeyPatch, tmp_path: Path, order: str
) -> None:
    """A result against itself (same order: read side by side) or against its rows reversed (beyond a
    summary limit of 500 rows: hash parts of ~256 rows) at 1000 and 4000 variants, blocks of BLOCK rows: the
    peak grows < 16 B per variant of the 3000 more (+ 128 KiB); measured 6 (same) and 7 (reversed). Before:
    both tables whole and eight arrays per compared column, 2467 B per variant."""
    from crashstudy.analysis import compare_match

    monkeypatch.setattr(compare_inputs, "WHOLE_ROWS", 100)
    monkeypatch.setattr(compare_match, "PART_ROWS", BLOCK)
    monkeypatch.setattr(reader, "READ_BLOCK", BLOCK)
    monkeypatch.setattr(reader, "SUMMARY_ROWS_MAX", 500)
    peaks = {}
    for n in ("1000", "4000"):
        base = moved[n]
        if order == "reversed":
            base = _with_summary(
                base, tmp_path / n, pd.read_parquet(base / "summary.parquet").iloc[::-1], BLOCK
            )
        if n == "1000":
            _warm_call(
                ["compare", str(moved[n]), str(base)]
            )  # the first call's imports and caches (not per folder)
        peaks[n] = _command_peak(["compare", str(moved[n]), str(base)])
    assert peaks["4000"] - peaks["1000"] < 3000 * 16 + 128 * 1024, peaks
