"""``crashstudy compare`` of large results block by block (issue 19, analysis/compare_stream.py): what it
prints and writes is what the whole-table comparison prints and writes on the same inputs; its memory does
not grow with the variants; another order beyond the whole-table limit is refused with what to do.
Small N with small row groups (the large sizes live in benchmarks/scale.py)."""

from __future__ import annotations

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
from crashstudy.results import reader, tables
from crashstudy.results.reader import open_results
from crashstudy.run import runner
from crashstudy.study.plan import load_study
from helpers import reseal

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from scale import write_study  # noqa: E402 - the 2-spring study of the scale benchmark

BLOCK = 256  # rows per Parquet row group of the runs here, and per block read


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The 2-spring study at 1000 and 4000 variants (reference kernel, row groups of BLOCK rows), and a copy
    of the 1000 whose summary moved: a metric by 1e-3 (past tolerance) and by 1e-9 (within), NaN against
    numbers in two columns (ties of infinite score), status changes both ways; row groups of 300 rows (the
    two tables' blocks do not line up). Also the baseline's rows in reverse order."""
    root = tmp_path_factory.mktemp("compare-stream")
    out = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(tables, "SUMMARY_BLOCK", BLOCK)
        for size in (1000, 4000):
            study = write_study(root / str(size), size)
            out[str(size)] = root / str(size) / "out"
            runner.run_plan(load_study(study), out[str(size)], kernel="reference", chunk=4096, progress=False)
    df = pd.read_parquet(out["1000"] / "summary.parquet")
    df.loc[10:60, "peak_force.s2"] *= 1.0 + 1e-3
    df.loc[100:400, "t_end"] *= 1.0 + 1e-9
    df.loc[[7, 300, 301, 900], "peak_force.s1"] = np.nan
    df.loc[[300, 555], "max_crush.s2"] = np.nan
    status = df["status"].astype(str).to_numpy()
    reason = df["failure_reason"].astype(object).fillna("").astype(str).to_numpy()
    status[[5, 250, 251, 999]], reason[[5, 250, 251, 999]] = "failed", "crushed to zero length"
    df["status"], df["failure_reason"] = pd.Categorical(status), pd.Categorical(reason)
    out["moved"] = _with_summary(out["1000"], root / "moved", df, 300)
    baseline = pd.read_parquet(out["1000"] / "summary.parquet")
    out["reversed"] = _with_summary(out["1000"], root / "reversed", baseline.iloc[::-1], BLOCK)
    baseline.loc[[250, 600], "status"] = "failed"  # failed -> ok in "moved" at 600, failed -> failed at 250
    out["baseline"] = _with_summary(out["1000"], root / "baseline", baseline, BLOCK)
    return out


def _with_summary(folder: Path, dest: Path, df: pd.DataFrame, rows: int) -> Path:
    """A copy of the result ``folder`` whose summary.parquet is ``df`` (row groups of ``rows``), resealed."""
    shutil.copytree(folder, dest)
    pq.write_table(pa.Table.from_pandas(df.reset_index(drop=True), preserve_index=False), dest / "summary.parquet",
                   row_group_size=rows)
    reseal(dest)
    return dest


def _everything(new: Path, base: Path) -> tuple[object, str, bytes]:
    """(the comparison, its report, its JUnit XML) of ``new`` against ``base``."""
    import xml.etree.ElementTree as ET

    cmp = compare(new, base)
    return cmp, cmp.report(), ET.tostring(cmp.to_junit().getroot())


def test_streamed_compare_prints_and_writes_what_the_whole_table_compare_does(
    results: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """Independent truth: the whole-table comparison (outer merge on the axis values) of the same two folders.
    Streamed (WHOLE_ROWS 100, blocks of BLOCK rows against row groups of 300): the same report, JUnit XML,
    counts, per-metric table and top rows; no per-variant arrays."""
    whole, w_text, w_xml = _everything(results["moved"], results["baseline"])
    assert not whole.streamed and len(whole.matched) == 1000  # type: ignore[attr-defined]
    monkeypatch.setattr(compare_inputs, "WHOLE_ROWS", 100)
    monkeypatch.setattr(reader, "READ_BLOCK", BLOCK)
    part, p_text, p_xml = _everything(results["moved"], results["baseline"])
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


def test_another_order_is_matched_whole_up_to_the_limit_and_refused_beyond_it(
    results: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A baseline in reverse row order: read whole and matched by axis values (the same report as in order);
    beyond the Results objects' summary_limit an InputError says why and what to do."""
    want = _everything(results["moved"], results["1000"])[1]
    monkeypatch.setattr(compare_inputs, "WHOLE_ROWS", 100)
    cmp, text, _ = _everything(results["moved"], results["reversed"])
    assert not cmp.streamed and text == want.replace(str(results["1000"]), str(results["reversed"]))  # type: ignore[attr-defined]
    new, base = open_results(results["moved"]), open_results(results["reversed"])
    base.summary_limit = 500
    with pytest.raises(InputError, match=r"same order \(row 0: nodes.m2.mass is 1 in the new summary, 3 in the baseline's\).*"
                       r"re-run of the baseline's study"):
        compare(new, base)
    new.close()
    base.close()


def _compare_peak(folder: Path) -> int:
    """Peak bytes of ``crashstudy compare DIR DIR`` here: traced (Python, NumPy) plus pyarrow's pool peak."""
    import contextlib
    import io
    import tracemalloc

    from crashstudy.cli.main import main

    pool, before = pa.proxy_memory_pool(pa.default_memory_pool()), pa.default_memory_pool()
    pa.set_memory_pool(pool)
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(["compare", str(folder), str(folder)]) == 0
        return tracemalloc.get_traced_memory()[1] + pool.max_memory()
    finally:
        tracemalloc.stop()
        pa.set_memory_pool(before)


def test_compare_of_a_large_result_does_not_grow_with_the_variants(
    results: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A result against itself at 1000 and 4000 variants, streamed (WHOLE_ROWS 100, blocks of BLOCK rows): the
    peak grows < 16 B per variant of the 3000 more (+ 128 KiB); measured 6. Before: both tables whole and
    eight arrays per compared column, 2467 B per variant."""
    monkeypatch.setattr(compare_inputs, "WHOLE_ROWS", 100)
    monkeypatch.setattr(reader, "READ_BLOCK", BLOCK)
    peaks = {}
    for n in ("1000", "4000"):
        _compare_peak(results[n])  # warm: imports and caches of the first call
        peaks[n] = _compare_peak(results[n])
    assert peaks["4000"] - peaks["1000"] < 3000 * 16 + 128 * 1024, peaks
