"""Issue 19, the readers' scratch files: the part files of ``compare``'s hash-partitioned merge (GBs at 10^8
variants) live in ``TMPDIR/crashstudy-scratch-<pid>-...``; a reader killed by SIGKILL leaves its folder, and
the next reader that makes one removes every such folder whose process no longer runs (before: a
``crashstudy-compare-*`` folder that stayed in TMPDIR for good)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from crashstudy.results import scratch, tables
from crashstudy.run import runner
from crashstudy.study.plan import load_study
from helpers import reseal

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from scale import write_study  # noqa: E402 - the 2-spring study of the scale benchmark

CHILD = """
import os, signal, sys
from crashstudy.analysis import compare_inputs, compare_match
from crashstudy.analysis.compare import compare
from crashstudy.results import reader
from crashstudy.results.reader import open_results

compare_inputs.WHOLE_ROWS, compare_match.PART_ROWS, reader.READ_BLOCK = 100, 200, 256
if sys.argv[3] == "kill":  # every part written, then killed before the first is read back
    compare_match._read = lambda *a: os.kill(os.getpid(), signal.SIGKILL)
new, base = open_results(sys.argv[1]), open_results(sys.argv[2])
new.summary_limit = base.summary_limit = 500  # beyond it: the hash-partitioned merge
print(compare(new, base).n_matched, "matched")
"""


@pytest.fixture(scope="module")
def pair(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A 1000-variant 2-spring result (reference kernel) and a copy with its summary rows reversed."""
    root = tmp_path_factory.mktemp("scratch")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(tables, "SUMMARY_BLOCK", 256)
        study = write_study(root / "s", 1000)
        runner.run_plan(load_study(study), root / "out", kernel="reference", chunk=4096, progress=False)
    rev = root / "rev"
    shutil.copytree(root / "out", rev)
    df = pd.read_parquet(rev / "summary.parquet").iloc[::-1].reset_index(drop=True)
    pq.write_table(
        pa.Table.from_pandas(df, preserve_index=False), rev / "summary.parquet", row_group_size=256
    )
    reseal(rev)
    return root / "out", rev


def _compare(pair: tuple[Path, Path], tmp: Path, how: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "TMPDIR": str(tmp)}
    cmd = [sys.executable, "-c", CHILD, str(pair[0]), str(pair[1]), how]
    return subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)


def _scratch(tmp: Path) -> list[Path]:
    return sorted(p for p in tmp.iterdir() if p.name.startswith(scratch.PREFIX))


def test_a_compare_killed_by_sigkill_leaves_a_folder_that_the_next_compare_removes(
    pair: tuple[Path, Path], tmp_path: Path
) -> None:
    """Killed after writing its 2 x 5 part files: one folder named by the dead pid, holding them. The next
    compare (run to the end) removes it and its own, and leaves alone a folder whose process runs (this
    test's), one of the same dead pid on another host (a TMPDIR shared between machines) and a link that
    only looks like a dead one's folder (its target untouched)."""
    killed = _compare(pair, tmp_path, "kill")
    assert killed.returncode == -signal.SIGKILL, killed.stderr[-2000:]
    left = _scratch(tmp_path)
    assert len(left) == 1 and scratch.owner_pid(left[0].name) not in (None, os.getpid())
    assert len(list(left[0].iterdir())) == 10  # 5 parts a side
    dead, host = left[0].name.split("-")[2:4]  # crashstudy-scratch-<pid>-<host>-compare-...
    alive = tmp_path / f"{scratch.PREFIX}{os.getpid()}-{host}-compare-running"
    other_host = tmp_path / f"{scratch.PREFIX}{dead}-{'0' * 8 if host != '0' * 8 else '1' * 8}-compare-x"
    for folder in (alive, other_host):
        folder.mkdir()
    target = tmp_path / "kept"
    target.mkdir()
    (target / "f").write_text("x")
    link = tmp_path / f"{scratch.PREFIX}{dead}-{host}-compare-link"
    link.symlink_to(target)
    done = _compare(pair, tmp_path, "run")
    assert done.returncode == 0 and done.stdout.split() == ["1000", "matched"], done.stderr[-2000:]
    assert _scratch(tmp_path) == sorted([alive, link, other_host])
    assert (target / "f").read_text() == "x"


def test_a_scratch_folder_is_removed_when_its_reader_ends_or_fails(tmp_path: Path) -> None:
    """Left normally or by an exception: no folder stays (the folder was there while it ran)."""
    seen = []
    with pytest.raises(RuntimeError), scratch.scratch_folder("ranks") as f:
        seen.append(f)
        (f / "b0").write_bytes(b"0" * 10)
        raise RuntimeError
    with scratch.scratch_folder("ranks") as g:
        seen.append(g)
        assert g.is_dir() and scratch.owner_pid(g.name) == os.getpid()
    assert not any(p.exists() for p in seen)
