"""What any numba tool that writes these results pays, against ``crashstudy run`` (issue 25: the cells the
matrix cannot bring within 2x of a hand loop's kernel).

``matrix.py`` divides crashstudy's end-to-end time by the hand loop's *kernel* time. Where that kernel takes
a few hundredths of a second (10^3 variants) or where the results are large beside it (10^6 short
variants), no program that starts a process, loads numba-compiled code and writes the same files can come
within 2x of it. This script measures that floor, part by part, each in fresh processes on warm caches, and
``crashstudy run`` (the command line, warm) beside it:

- ``numba_start_s``: a fresh ``python`` that imports numba and calls a cached ``@njit`` function (interpreter,
  numpy and numba imports, and numba's per-process set-up before its first compiled call);
- ``write_s``: a fresh process writing the variables of crashstudy's ``results.nc`` of the same study (same
  names, shapes and types; netCDF4, contiguous, no checksums or texts) and its ``summary.parquet`` table
  (pyarrow, dictionary pages for the text columns only) from memory, the imports of netCDF4 and pyarrow included, the reading before it not;
- ``loop_kernel_s``: the hand loop's kernel time (``matrix.py``'s cell, same variants and steps);
- ``floor_s`` = the three summed; ``cli_s``: ``crashstudy run STUDY -o OUT --force``, warm, the process's wall
  time; ``ratio`` = cli_s / floor_s. Medians of ``--repeats`` fresh processes each, the kinds alternated.

Run: ``python benchmarks/floor.py [--repeats 5]``. Writes ``benchmarks/results/floor.md``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, load, machine, machine_md, md_table, median  # noqa: E402

CELLS = [("2spring", "scale", 1000), ("frontal", "masses", 1000), ("2spring", "scale", 1_000_000)]
NUMBA_PROBE = """\
import numba

@numba.njit(cache=True)
def twice(x):
    return 2.0 * x
"""


def _numba_start(folder: Path) -> float:
    """Seconds of a fresh process that imports numba and calls a cached compiled function."""
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, "-c", "import probe; probe.twice(1.0)"],
        check=True,
        cwd=folder,
        env={"PATH": "/usr/bin:/bin", "NUMBA_CACHE_DIR": str(folder / "cache"), "PYTHONPATH": str(folder)},
    )
    return time.perf_counter() - t0


def write_only(out: Path, target: Path) -> float:
    """In this (fresh) process: read ``out``'s results.nc variables and summary table, then write them
    anew under ``target``; returns the seconds of the imports of the writers plus the writing."""
    t0 = time.perf_counter()
    import netCDF4
    import numpy as np
    import pyarrow.parquet as pq

    imports = time.perf_counter() - t0
    with netCDF4.Dataset(out / "results.nc") as src:
        src.set_auto_mask(False)
        src.set_auto_chartostring(False)
        dims = {d: len(v) for d, v in src.dimensions.items()}
        data = {n: (v.dimensions, np.asarray(v[:])) for n, v in src.variables.items() if v.dtype != str}
    table = pq.read_table(out / "summary.parquet")
    t1 = time.perf_counter()
    with netCDF4.Dataset(target / "results.nc", "w") as dst:
        for d, n in dims.items():
            dst.createDimension(d, n)
        for name, (vdims, arr) in data.items():
            whole = all(dims[d] for d in vdims)  # (netCDF has no contiguous variable of a 0-length dimension)
            dst.createVariable(name, arr.dtype, vdims, contiguous=whole)[:] = arr
    texts = [f.name for f in table.schema if str(f.type).startswith("dictionary")]
    pq.write_table(table, target / "summary.parquet", use_dictionary=texts)  # (floats: plain, as crashstudy)
    return imports + time.perf_counter() - t1


def _write(out: Path, target: Path) -> float:
    proc = subprocess.run(
        [sys.executable, __file__, "--write-only", str(out), str(target)],
        capture_output=True,
        text=True,
        check=True,
    )
    return float(proc.stdout.strip().splitlines()[-1])


def _cli(study: Path, out: Path) -> float:
    t0 = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "crashstudy.cli", "run", str(study), "-o", str(out), "--force"],
        check=True,
        capture_output=True,
    )
    return time.perf_counter() - t0


def _loop_kernel(model: str, kind: str, size: int, folder: Path) -> dict[str, Any]:
    """matrix.py's warm cell: crashstudy in process and the hand loop's kernel time."""
    folder.mkdir(exist_ok=True)
    cell = {"model": model, "kind": kind, "size": size, "cache": "warm", "threads": 2, "folder": str(folder)}
    proc = subprocess.run(
        [sys.executable, str(Path(__file__).parent / "matrix.py"), "--one", json.dumps(cell)],
        capture_output=True,
        text=True,
        check=True,
    )
    return dict(json.loads(proc.stdout.strip().splitlines()[-1]))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--write-only", nargs=2, help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, default=RESULTS / "floor.md")
    args = ap.parse_args()
    if args.write_only:
        print(write_only(Path(args.write_only[0]), Path(args.write_only[1])))
        return
    from matrix import MODEL_SPECS, SHORT_FROM, study_text

    start = load()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        (work / "probe.py").write_text(NUMBA_PROBE)
        _numba_start(work)  # compiles the probe into its cache
        for model, kind, size in CELLS:
            spec = MODEL_SPECS[model]
            end = spec["end"][int(size >= SHORT_FROM)]
            text = spec["text"].replace("END", str(end)) if "text" in spec else Path(spec["file"]).read_text()
            mfile = work / f"{model}.yaml"
            mfile.write_text(text)
            study = work / f"{model}-{kind}-{size}.yaml"
            study.write_text(study_text(model, kind, size, mfile))
            out, again = work / "out", work / "again"
            again.mkdir(exist_ok=True)
            _cli(study, out)  # warm: the kernels compiled, the cache written
            subprocess.run(
                [sys.executable, str(Path(__file__).parent / "prerun_scale.py"), "--wait", str(study)],
                check=True,
            )
            cell = _loop_kernel(model, kind, size, work / "cell")
            times: dict[str, list[float]] = {"numba_start_s": [], "write_s": [], "cli_s": []}
            for _ in range(args.repeats):
                times["cli_s"].append(_cli(study, out))
                times["numba_start_s"].append(_numba_start(work))
                times["write_s"].append(_write(out, again))
            row: dict[str, Any] = {"model": model, "kind": kind, "variants": size}
            row.update({k: round(median(v), 3) for k, v in times.items()})
            row["loop_kernel_s"] = round(cell["loop_s"], 3)
            row["floor_s"] = round(row["numba_start_s"] + row["write_s"] + row["loop_kernel_s"], 3)
            row["ratio"] = round(row["cli_s"] / row["floor_s"], 2)
            row["matrix_ratio"] = round(row["cli_s"] / cell["loop_s"], 1)
            print(row, flush=True)
            rows.append(row)
    cols = [
        "model",
        "kind",
        "variants",
        "numba_start_s",
        "write_s",
        "loop_kernel_s",
        "floor_s",
        "cli_s",
        "ratio",
    ]
    text = (
        "# The floor of a numba tool that writes these results, and crashstudy run (benchmarks/floor.py)\n\n"
        "See the script's docstring. ratio = cli_s / floor_s; matrix_ratio = cli_s / loop_kernel_s (the "
        "matrix's measure, here with the command line's whole process).\n\n"
        + md_table(rows, [*cols, "matrix_ratio"])
        + "\n\n"
        + machine_md(machine(start))
        + "\n"
    )
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
