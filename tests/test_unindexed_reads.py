"""The command line's reads of a finished store need no xarray (reader.Results.stored):
the after-run warnings and the summary tables read back from the store are those of the indexed
dataset, and a run no longer imports dask (xarray imported it to ask whether the small dimension
coordinates' indexes were dask arrays: 0.3 CPU s of a 10^6-variant run's after-run checks).
Also: a matrix over initial velocities only, with a fixed dt, runs (the fixed-dt check raised a
ValueError traceback: no dimension changed the critical step)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

# a nonlinear and a linear spring, a fixed dt; the 20 and 40 m/s impacts take the nonlinear spring past both
# ends of its curve, 5 m/s does not
MODEL = """\
name: curve-ends
units: SI
curves:
  soft: {x: [-0.03, -0.01, 0.0, 0.01, 0.03], y: [-2.0e4, -5.0e3, 0.0, 5.0e3, 2.0e4]}
nodes:
  wall: {position: [0.0], fixed: true}
  m1: {position: [0.5], mass: 1.0}
  m2: {position: [1.0], mass: 50.0}
springs:
  s1: {nodes: [wall, m1], material: {type: nonlinear_elastic, curve: soft}}
  s2: {nodes: [m1, m2], material: {type: linear_elastic, stiffness: 4.0e5}}
initial_velocity: {m2: [-5.0]}
end_time: 0.05
time_step: {dt: 1.0e-4}
output: {histories: none}
"""
STUDY = "name: ends\nmodel: model.yaml\nmatrix:\n  impact_velocity: [5.0, 20.0, 40.0]\n"

_RUN = """\
import json, sys
sys.path.insert(0, sys.argv[1])
from helpers import run_cli
p = run_cli("run", "study.yaml", "-o", "out")
print(json.dumps([p.returncode, p.stdout, p.stderr, "dask" in sys.modules, "pandas" in sys.modules, "xarray" in sys.modules]))
"""


def test_after_run_and_summary_from_the_unindexed_store(tmp_path: Path) -> None:
    (tmp_path / "model.yaml").write_text(MODEL)
    (tmp_path / "study.yaml").write_text(STUDY)
    here = str(Path(__file__).resolve().parent)
    proc = subprocess.run(
        [sys.executable, "-c", _RUN, here], capture_output=True, text=True, cwd=tmp_path, timeout=600
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    rc, out, err, dask, pandas, xarray = json.loads(proc.stdout.splitlines()[-1])
    assert rc == 0 and "Traceback" not in err, err  # before: ValueError in the fixed-dt check
    assert not dask  # before: imported by the after-run checks' default indexes
    # nor xarray: the summary tables are streamed through pyarrow, and the after-run checks read the store
    # through the netCDF4 API (Results.stored). (pandas is: pyarrow imports it for its first array.)
    assert pandas and not xarray

    import crashstudy
    from crashstudy.results.curve_ends import warnings_of
    from crashstudy.results.tables import write_summary

    res = crashstudy.open_results(tmp_path / "out")
    with res.stored() as nc:
        want = warnings_of(nc)
    with res.raw_dataset as indexed:
        (tmp_path / "again").mkdir()
        write_summary(indexed, tmp_path / "again", csv=True)
    assert want and all(f"warning: {w}" in err for w in want), (want, err)
    # and from the summary itself: the variants whose inner spring went past its first point
    codes = res.summary["past_curve_end.s1"].to_numpy(dtype=float)
    first = int(np.isin(codes, (1.0, 3.0)).sum())
    assert first >= 1 and f"spring s1 was compressed past its curve's first point in {first} " in err
    # and the springs named are those whose summary codes say so (s2 is linear: no curve)
    assert len(want) == 1 and want[0].startswith("spring s1 was compressed past its curve's first point")
    for name in ("summary.parquet", "summary.csv"):  # the run's tables (read back unindexed): same bytes
        assert (tmp_path / "out" / name).read_bytes() == (tmp_path / "again" / name).read_bytes(), name
    table = pd.read_parquet(tmp_path / "out" / "summary.parquet")
    assert list(table["impact_velocity"]) == [5.0, 20.0, 40.0]
