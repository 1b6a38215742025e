"""Issue 19, ``crashstudy plot --kind matrix`` on a large result: beyond ``--max-points`` variants the panels
are 2-D histograms counted block by block (the summary's row groups; bins from the Parquet statistics, else
from a first pass), the diagonal 1-D histograms; up to it the exact figure as before. Truth: NumPy's
histogram2d / histogram of the whole columns (exact counts), and the memory of the command at two sizes."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from crashstudy.analysis import plot_density
from crashstudy.cli.main import main
from crashstudy.results import reader, tables
from crashstudy.run import runner
from crashstudy.study.plan import load_study
from helpers import reseal

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from scale import write_study  # noqa: E402 - the 2-spring study of the scale benchmark (masses m1 x m2)

X, Y, METRIC = "nodes.m2.mass", "nodes.m1.mass", "peak_force.s2"  # the study axes in order


@pytest.fixture(scope="module")
def result(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 1000-variant 2-spring result (reference kernel) whose summary has 4 failed variants and a NaN
    metric in a variant that ran, in row groups of 256 rows (resealed)."""
    root = tmp_path_factory.mktemp("plot-large")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(tables, "SUMMARY_BLOCK", 256)
        study = write_study(root / "s", 1000)
        runner.run_plan(load_study(study), root / "out", kernel="reference", chunk=4096, progress=False)
    df = pd.read_parquet(root / "out" / "summary.parquet")
    status = df["status"].astype(str).to_numpy()
    status[[3, 400, 401, 998]] = "failed"
    df["status"] = pd.Categorical(status)
    df.loc[[3, 401], METRIC] = np.nan
    df.loc[17, METRIC] = np.nan  # ran, but no value
    return _with_summary(root / "out", df)


def _with_summary(folder: Path, df: pd.DataFrame, dest: Path | None = None, **kw: Any) -> Path:
    if dest is not None:
        shutil.copytree(folder, dest)
        folder = dest
    pq.write_table(pa.Table.from_pandas(df, preserve_index=False), folder / "summary.parquet", **kw)
    reseal(folder)
    return folder


@pytest.fixture
def drawn(monkeypatch: pytest.MonkeyPatch) -> list[tuple[plot_density.Density, Any]]:
    """The densities the command counted and the figures it drew of them."""
    seen: list[tuple[plot_density.Density, Any]] = []
    real = plot_density.plot_density
    monkeypatch.setattr(
        plot_density, "plot_density", lambda d, *a: seen.append((d, real(d, *a))) or seen[-1][1]
    )
    monkeypatch.setattr(reader, "READ_BLOCK", 100)  # blocks that do not line up with the row groups
    return seen


def _plot(folder: Path, out: Path, *extra: str) -> None:
    argv = ["plot", str(folder), "--kind", "matrix", "--quantity", METRIC, "-o", str(out), *extra]
    assert main(argv) == 0


def _truth(folder: Path, names: list[str]) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """(bin edges from the whole columns' min and max, the columns' values of the rows that ran)."""
    df = pd.read_parquet(folder / "summary.parquet")
    edges = [np.linspace(df[n].min(), df[n].max(), plot_density.BINS + 1) for n in names]
    ok = (df["status"].astype(str) == "ok") & df[names].notna().all(axis=1)
    return edges, [df.loc[ok, n].to_numpy(dtype=float) for n in names]


@pytest.mark.parametrize("statistics", [True, False])
def test_streamed_counts_equal_numpy_histograms_of_the_whole_columns(
    result: Path, tmp_path: Path, drawn: list, statistics: bool
) -> None:
    """--max-points 500 < 1000 variants: one density figure of m2, m1 and the metric, counted in blocks of
    100 rows over row groups of 256 (bins from the Parquet statistics, or without them from a first pass):
    edges and every count exactly those of numpy.histogram / histogram2d of the whole columns; 5 variants
    skipped (4 failed, 1 NaN), the panel drawn is the count, the note says what the figure is."""
    folder = result
    if not statistics:
        df = pd.read_parquet(result / "summary.parquet")
        folder = _with_summary(result, df, tmp_path / "nostats", write_statistics=False, row_group_size=256)
        assert pq.ParquetFile(folder / "summary.parquet").metadata.row_group(0).column(1).statistics is None
    _plot(folder, tmp_path / "png", "--max-points", "500")
    assert len(drawn) == 1 and (tmp_path / "png" / f"matrix-{METRIC}.png").stat().st_size > 10_000
    d, fig = drawn[0]
    names = [X, Y, METRIC]
    assert d.names == names and (d.counted, d.skipped) == (995, 5)
    edges, values = _truth(folder, names)
    for i in range(3):
        assert np.array_equal(d.edges[i], edges[i])
        assert np.array_equal(d.counts1[i], np.histogram(values[i], edges[i])[0])
        for j in range(i):
            want = np.histogram2d(values[j], values[i], bins=[edges[j], edges[i]])[0]
            assert np.array_equal(d.counts2[i, j], want) and want.sum() == 995
    mesh = fig.axes[3].collections[0].get_array()  # row 1, column 0: m1 (up) over m2 (across)
    assert np.array_equal(np.ma.filled(mesh, 0).reshape(100, 100), d.counts2[1, 0].T)
    text = " ".join(t.get_text() for t in fig.texts) + fig._suptitle.get_text()
    assert "2-D density" in text and "995 variants" in text and "--max-points 500" in text


def test_up_to_the_limit_the_exact_heat_map_is_drawn(result: Path, tmp_path: Path, drawn: list) -> None:
    """1000 variants, default --max-points (10^6): no density counted; the heat map as before."""
    _plot(result, tmp_path / "png", "--x", X, "--y", Y)
    assert drawn == [] and (tmp_path / "png" / f"matrix-{METRIC}-{X}-{Y}.png").is_file()


def test_a_large_density_matrix_does_not_hold_the_columns(
    result: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The summary tiled to 5 x 10^4 and 3 x 10^5 rows (the three columns drawn, whole, 6 MB more at the
    larger size): the command's peak (traced Python and NumPy memory plus pyarrow's pool) grows by less than
    1 MiB (measured: 2.30 and 2.02 MB; the exact figure, --max-points 10^8, took 17.2 and 55.8 MB). The
    figure is left out (its drawing is the same at any size, and the slow part under tracemalloc); drawn,
    the peak was 14.0 MB at both 10^5 and 10^6 rows."""
    import contextlib
    import io
    import tracemalloc

    from matplotlib.figure import Figure

    monkeypatch.setattr(plot_density, "plot_density", lambda *a: Figure())  # drawing: the same at any size
    monkeypatch.setattr(reader, "READ_BLOCK", 8192)
    base = pd.read_parquet(result / "summary.parquet", columns=["variant", X, Y, "status", METRIC])
    peaks = {}
    for n in (50_000, 300_000):
        df = pd.concat([base] * (n // len(base)), ignore_index=True)
        df["variant"] = np.arange(n)
        folder = _with_summary(result, df, tmp_path / str(n), row_group_size=8192)
        pool, before = pa.proxy_memory_pool(pa.default_memory_pool()), pa.default_memory_pool()
        pa.set_memory_pool(pool)
        tracemalloc.start()
        try:
            tracemalloc.reset_peak()
            with contextlib.redirect_stdout(io.StringIO()):
                _plot(folder, tmp_path / f"png{n}", "--max-points", "1000")
            peaks[n] = tracemalloc.get_traced_memory()[1] + pool.max_memory()
        finally:
            tracemalloc.stop()
            pa.set_memory_pool(before)
    assert peaks[300_000] - peaks[50_000] < 2**20, peaks


def test_max_points_zero_always_draws_the_density_and_a_negative_one_is_refused(
    result: Path, tmp_path: Path, drawn: list, capsys: pytest.CaptureFixture[str]
) -> None:
    """--max-points 0: the density matrix of 1000 variants (x and the metric with --y none); -1: exit 2 and
    a message naming the folder and the option, no traceback."""
    _plot(result, tmp_path / "png", "--max-points", "0", "--y", "none")
    assert [d.names for d, _ in drawn] == [[X, METRIC]]
    argv = ["plot", str(result), "--kind", "matrix", "-o", str(tmp_path / "bad"), "--max-points", "-1"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert str(result) in err and "--max-points -1" in err and "Traceback" not in err


def test_an_older_folder_with_summary_csv_gives_the_same_counts(
    result: Path, tmp_path: Path, drawn: list, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same summary as summary.csv (a folder of an older version, no Parquet statistics): bins from a
    first pass, the same edges and counts as from summary.parquet. (The counts are the subject: the two
    figures are built but not rendered to PNG, which was most of this test's CPU; the PNG itself is
    checked by the streamed-counts test.)"""
    from matplotlib.figure import Figure

    monkeypatch.setattr(Figure, "savefig", lambda self, fh, **kw: fh.write(b"not rendered"))
    older = tmp_path / "older"
    shutil.copytree(result, older)
    pd.read_parquet(older / "summary.parquet").to_csv(older / "summary.csv", index=False)
    (older / "summary.parquet").unlink()
    reseal(older)
    for folder in (result, older):
        _plot(folder, tmp_path / folder.name, "--max-points", "0")
    (a, _), (b, _) = drawn
    assert (a.counted, a.skipped) == (b.counted, b.skipped) == (995, 5)
    assert all(np.array_equal(p, q) for p, q in zip(a.edges + a.counts1, b.edges + b.counts1, strict=True))
    assert all(np.array_equal(a.counts2[k], b.counts2[k]) for k in a.counts2)
