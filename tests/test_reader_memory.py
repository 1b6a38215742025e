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
