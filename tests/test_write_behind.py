"""A chunk's results written on a writer thread while the next chunk computes (issue 25, run/write_behind.py).

Truth: the same run written in the main thread (``write_behind.THREADED = False``, the runner as it was).
A 1-D mass on a linear spring (k = 100 N/m, m = 1..4 kg, v0 = 1 m/s), 24 variants in chunks of 5 (five
hand-overs, the last one short), histories kept, on the NumPy reference (no compile). The threaded run's
files must equal the unthreaded run's byte for byte (results.nc, summary.parquet, manifest.json: run id and
checksums included), and its peak force the closed form v0 sqrt(k m) sin(t sqrt(k / m)) (rel 2e-3).
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
import yaml

import crashstudy.run.write_behind as wb
from crashstudy import open_results
from crashstudy.results.store import ResultWriter
from crashstudy.run.runner import run_plan
from crashstudy.study.plan import load_study
from folders import MODEL, peak_force

MASSES = [1.0, 1.5, 2.0, 2.5, 3.0, 4.0]
SPEEDS = [0.5, 1.0, 1.5, 2.0]


def _plan(tmp: Path):  # type: ignore[no-untyped-def]
    (tmp / "model.yaml").write_text(yaml.safe_dump(MODEL, sort_keys=False))
    study = {
        "name": "behind",
        "model": "model.yaml",
        "matrix": {"nodes.b.mass": MASSES, "impact_velocity": SPEEDS},
    }
    (tmp / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    return load_study(tmp / "study.yaml")


def _run(tmp: Path, out: str, threaded: bool, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setattr(wb, "THREADED", threaded)
    run_plan(_plan(tmp), tmp / out, kernel="reference", chunk=5, progress=False)
    return tmp / out


def test_results_written_behind_the_kernel_equal_those_written_in_the_main_thread_byte_for_byte(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    threads: set[str] = set()
    real = ResultWriter.write

    def write(self, res):  # type: ignore[no-untyped-def]
        threads.add(threading.current_thread().name)
        return real(self, res)

    monkeypatch.setattr(ResultWriter, "write", write)
    main = _run(tmp_path, "main", False, monkeypatch)
    assert threads == {threading.current_thread().name}
    threads.clear()
    behind = _run(tmp_path, "behind", True, monkeypatch)
    assert len(threads) == 1 and threads != {threading.current_thread().name}  # written on the writer thread
    names = sorted(p.name for p in main.iterdir() if p.is_file() and not p.name.startswith("."))
    assert names == sorted(p.name for p in behind.iterdir() if p.is_file() and not p.name.startswith("."))
    for name in names:
        assert (main / name).read_bytes() == (behind / name).read_bytes(), name
    s = open_results(behind).summary
    v0 = s["impact_velocity"].to_numpy()
    want = v0 * np.array([peak_force(m) for m in s["nodes.b.mass"]])
    np.testing.assert_allclose(s["peak_force.s"].to_numpy(), want, rtol=2e-3)
    assert len(s) == len(MASSES) * len(SPEEDS)


def test_a_write_that_fails_on_the_writer_thread_fails_the_run_and_leaves_a_resumable_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real = ResultWriter.write
    calls = []

    def write(self, res):  # type: ignore[no-untyped-def]
        calls.append(int(res.index[0]))
        if len(calls) == 3:
            raise OSError(28, "No space left on device")
        return real(self, res)

    monkeypatch.setattr(ResultWriter, "write", write)
    with pytest.raises(OSError, match="No space left"):
        _run(tmp_path, "R", True, monkeypatch)
    assert calls == [0, 5, 10]  # no chunk written after the failed one
    monkeypatch.setattr(ResultWriter, "write", real)
    run_plan(_plan(tmp_path), tmp_path / "R", kernel="reference", chunk=5, progress=False, resume=True)
    ref = _run(tmp_path, "ref", False, monkeypatch)
    a, b = open_results(tmp_path / "R").summary, open_results(ref).summary
    assert a.equals(b)


def test_writes_happen_in_order_one_at_a_time_and_close_raises_the_last_error() -> None:
    seen: list[int] = []
    busy = threading.Lock()

    def write(k: int) -> None:
        assert busy.acquire(blocking=False), "two writes at once"
        try:
            if k == 7:
                raise ValueError("bad chunk 7")
            seen.append(k)
        finally:
            busy.release()

    w = wb.WriteBehind(write, threaded=True)
    for k in range(7):
        w.put(k)
    w.close()
    assert seen == list(range(7))
    w = wb.WriteBehind(write, threaded=True)
    w.put(7)
    with pytest.raises(ValueError, match="bad chunk 7"):
        w.close()
