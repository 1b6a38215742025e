"""Issue 19: the 2-spring study at 10^5, 10^6, ... variants, each store, in-process and on a LocalCluster.

The model is ``benchmarks/matrix.py``'s 2-spring chain (two ``nonlinear_elastic`` springs, 1-D) at the short
end time (0.0086 s, 86 steps), histories none; the study crosses 100 masses of m1 with n / 100 masses
of m2. Each cell runs ``crashstudy run`` as a subprocess twice into the same folder (a fresh run, then a
re-run that reuses every variant), while psutil polls the resident set size of the command and of every
process it started (the Dask scheduler and workers of ``--scheduler local``) every 0.1 s. Recorded: wall
time, time per variant, the peak RSS of each process (the client's and the largest other's), the bytes
the result folder holds. The kernel is compiled once before the first cell (its cache is reused).

Usage::

    python benchmarks/scale.py                        # 10^5 and 10^6, netcdf and zarr in-process
    python benchmarks/scale.py --sizes 1e5 --dask     # also --scheduler local --store zarr

Options: ``--sizes`` (comma list), ``--stores`` (netcdf,zarr), ``--dask``, ``--work DIR``, ``--report FILE``
(default benchmarks/results/scale.md; ``-`` prints only).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import psutil

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, load, machine, machine_md, md_table  # noqa: E402
from matrix import TWO_SPRING  # noqa: E402

REPORT = RESULTS / "scale.md"


def write_study(folder: Path, n: int) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "model.yaml").write_text(TWO_SPRING.replace("END", "0.0086"))
    a = 100 if n >= 100 else 1
    m2 = [round(float(v), 9) for v in np.linspace(1.0, 3.0, n // a)]
    m1 = [round(float(v), 9) for v in np.linspace(0.5, 2.0, a)]
    study = folder / "study.yaml"
    study.write_text(f"name: scale-{n}\nmodel: model.yaml\nmatrix:\n  nodes.m2.mass: {m2}\n  nodes.m1.mass: {m1}\n")
    return study


def watch(cmd: list[str], cwd: Path, interval: float = 0.1) -> dict[str, Any]:
    """Run ``cmd``; the peak RSS of the command and of each process it started, and the wall time."""
    t0 = time.perf_counter()
    proc = psutil.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    peaks: dict[int, int] = {}
    while proc.poll() is None:
        try:
            procs = [proc, *proc.children(recursive=True)]
        except psutil.NoSuchProcess:
            procs = []
        for p in procs:
            try:
                peaks[p.pid] = max(peaks.get(p.pid, 0), p.memory_info().rss)
            except (psutil.NoSuchProcess, psutil.AccessDenied):
                pass
        time.sleep(interval)
    wall = time.perf_counter() - t0
    out, err = proc.communicate()
    client = peaks.pop(proc.pid, 0)
    return {"exit": proc.returncode, "wall": wall, "client": client, "others": sorted(peaks.values(), reverse=True),
            "stdout": out.strip(), "stderr": err.strip()[-1500:]}  # fmt: skip


def folder_bytes(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file() and not f.is_symlink())


def cell(work: Path, n: int, store: str, dask: bool) -> list[dict[str, Any]]:
    study = write_study(work / f"n{n}", n)
    out = work / f"n{n}" / f"out-{store}{'-dask' if dask else ''}"
    cmd = [sys.executable, "-m", "crashstudy.cli", "run", str(study), "-o", str(out), "--progress", "off",
           "--store", store] + (["--scheduler", "local"] if dask else [])  # fmt: skip
    rows = []
    for kind in ("fresh", "re-run"):
        r = watch(cmd + (["--force"] if kind == "fresh" else []), study.parent)
        if r["exit"] != 0:
            print(r["stderr"], file=sys.stderr)
        others = r["others"]
        rows.append({"variants": n, "store": store, "where": "LocalCluster(2)" if dask else "in-process", "run": kind,
                     "wall [s]": round(r["wall"], 1), "per variant [us]": round(1e6 * r["wall"] / n, 2),
                     "client peak RSS [MiB]": round(r["client"] / 2**20),
                     "other processes' peak RSS [MiB]": ", ".join(str(round(o / 2**20)) for o in others[:3]) or "-",
                     "bytes written [MB]": round(folder_bytes(out) / 1e6, 1), "load": load(), "exit": r["exit"]})  # fmt: skip
        print(rows[-1], flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="1e5,1e6")
    ap.add_argument("--stores", default="netcdf,zarr")
    ap.add_argument("--dask", action="store_true", help="also run --scheduler local --store zarr")
    ap.add_argument("--work", type=Path, default=None)
    ap.add_argument("--report", default=str(REPORT))
    args = ap.parse_args(argv)
    start = load()
    work = args.work or Path(tempfile.mkdtemp(prefix="crashstudy-scale-"))
    warm = write_study(work / "warm", 100)  # compile (or load) the kernel once, outside the figures
    subprocess.run([sys.executable, "-m", "crashstudy.cli", "run", str(warm), "-o", str(warm.parent / "out"),
                    "--progress", "off", "--force"], cwd=warm.parent, capture_output=True, check=False)  # fmt: skip
    rows: list[dict[str, Any]] = []
    for size in (int(float(s)) for s in args.sizes.split(",")):
        for store in args.stores.split(","):
            rows += cell(work, size, store, False)
        if args.dask:
            rows += cell(work, size, "zarr", True)
    text = ("# Scale: the 2-spring study (issue 19)\n\n" + machine_md(machine(start)) + "\n\n"
            + "Command: `python benchmarks/scale.py " + " ".join(argv or sys.argv[1:]) + "`; each cell runs "
            "`crashstudy run` fresh (`--force`) and then again (every variant reused); `load` is the 1-min load "
            "average after the run (the machine is shared: wall times are not comparable between rows).\n\n"
            + md_table(rows) + "\n")  # fmt: skip
    if args.report == "-":
        print(text)
    else:
        Path(args.report).write_text(text)
        print(f"wrote {args.report}")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("CRASHSTUDY_BACKGROUND_COMPILE", "0")
    raise SystemExit(main())
