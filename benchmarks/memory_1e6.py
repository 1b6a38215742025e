"""Peak memory and wall time of a 10^6-variant summary-only study (issue 3: "well under 2 GiB").

Runs ``crashstudy run`` as a subprocess on a 100 x 100 x 100 study of the frontal model
(``studies/models/frontal-9mass.yaml``: engine mass 120..210 kg x rail-loading curve scale
0.7..1.6 x impact speed 10..20 m/s, the ranges of ``studies/frontal-matrix.yaml``) with
``set: {output: {histories: none}}``. While it runs, the resident set size (RSS) of the process
tree (the command and any worker processes) is polled with psutil every 0.1 s; the peak of the
sum is reported with the wall time and the sizes of ``results.nc`` and ``summary.csv``. The report
goes to ``benchmarks/results/memory_1e6.md`` with the machine it ran on.

Usage::

    python benchmarks/memory_1e6.py                 # the full 10^6 variants (several minutes)
    python benchmarks/memory_1e6.py --per-axis 20   # 8000 variants, a quick check of the script
    python benchmarks/memory_1e6.py --jobs 2        # spread the chunks over two processes

Options: ``--per-axis N`` (values per axis; N^3 variants, default 100), ``--jobs N``, ``--keep``
(keep the result folder), ``--work DIR`` (where the study and results go, default a temporary
folder), ``--report FILE`` (default benchmarks/results/memory_1e6.md; ``-`` prints only).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import psutil

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "models" / "frontal-9mass.yaml"
REPORT = ROOT / "benchmarks" / "results" / "memory_1e6.md"
LIMIT = 2 * 2**30  # the requirement: well under 2 GiB


def study_text(n: int) -> str:
    """A study of n^3 variants over the frontal-matrix axes, histories off."""

    def values(lo: float, hi: float) -> str:
        return "[" + ", ".join(repr(round(float(v), 6)) for v in np.linspace(lo, hi, n)) + "]"

    return (
        f"name: frontal-memory-{n**3}\n"
        f"model: {MODEL}\n"
        "matrix:\n"
        f"  nodes.engine.mass: {values(120.0, 210.0)}\n"
        f"  curves.rail-loading.scale: {values(0.7, 1.6)}\n"
        f"  impact_velocity: {values(10.0, 20.0)}\n"
        "set: {output: {histories: none}}\n"
    )


def tree_rss(proc: psutil.Process) -> int:
    """Resident set size of a process and all its descendants, bytes."""
    total = 0
    try:
        procs = [proc, *proc.children(recursive=True)]
    except psutil.NoSuchProcess:
        return 0
    for p in procs:
        try:
            total += p.memory_info().rss
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            pass
    return total


def run(study: Path, out: Path, jobs: int, interval: float = 0.1) -> dict[str, Any]:
    cmd = [
        sys.executable,
        "-m",
        "crashstudy.cli",
        "run",
        str(study),
        "-o",
        str(out),
        "--jobs",
        str(jobs),
        "--progress",
        "off",
        "--force",
    ]
    t0 = time.perf_counter()
    proc = psutil.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    peak, peak_at, samples, n_procs = 0, 0.0, 0, 1
    timeline: list[tuple[float, int]] = []  # (seconds, RSS) every 10 s: shows whether memory grows
    while proc.poll() is None:
        rss = tree_rss(proc)
        now = time.perf_counter() - t0
        if not timeline or now - timeline[-1][0] >= 10.0:
            timeline.append((now, rss))
        if rss > peak:
            peak, peak_at = rss, time.perf_counter() - t0
        try:
            n_procs = max(n_procs, 1 + len(proc.children(recursive=True)))
        except psutil.NoSuchProcess:
            pass
        samples += 1
        time.sleep(interval)
    wall = time.perf_counter() - t0
    stdout, stderr = proc.communicate()
    return {
        "exit": proc.returncode,
        "wall": wall,
        "peak_rss": peak,
        "peak_at": peak_at,
        "samples": samples,
        "procs": n_procs,
        "stdout": stdout.strip(),
        "stderr": stderr.strip()[-2000:],
        "timeline": timeline,
    }


def machine() -> list[str]:
    cpu = platform.processor() or "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        commit = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(ROOT), "status", "--porcelain", "src"],
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        commit, dirty = "?", ""
    import netCDF4
    import numba

    import crashstudy

    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    return [
        f"- date: {_dt.datetime.now().isoformat(timespec='seconds')}",
        f"- machine: {platform.machine()}, {cpu}, {psutil.cpu_count(logical=True)} logical cores "
        f"({len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else '?'} usable), "
        f"{psutil.virtual_memory().total / 2**30:.1f} GiB RAM; load average at start "
        f"{load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (a shared machine)",
        f"- {platform.system()} {platform.release()}, Python {platform.python_version()}, "
        f"numpy {np.__version__}, numba {numba.__version__} ({numba.config.NUMBA_NUM_THREADS} threads), "
        f"netCDF4 {netCDF4.__version__} (HDF5 {netCDF4.__hdf5libversion__})",
        f"- crashstudy {crashstudy.__version__} from {Path(crashstudy.__file__).parent}, "
        + (
            f"commit {commit}{' + uncommitted changes in src/' if dirty else ''}"
            if Path(crashstudy.__file__).resolve().is_relative_to(ROOT / "src")
            else f"not this checkout's src/ (the checkout is at {commit})"
        ),
    ]


def timeline_rows(timeline: Any, wall: float) -> list[str]:
    rows, next_t = [], 0.0
    for t, rss in timeline:
        if t >= next_t:
            rows.append(f"| {t:,.0f} | {mib(rss)} |")
            next_t = t + wall / 10
    return rows


def mib(n: float) -> str:
    return f"{n / 2**20:,.1f} MiB"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--per-axis", type=int, default=100)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--keep", action="store_true")
    ap.add_argument("--work")
    ap.add_argument("--report", default=str(REPORT))
    args = ap.parse_args(argv)

    n = args.per_axis
    work = Path(args.work) if args.work else Path(tempfile.mkdtemp(prefix="crashstudy-mem-"))
    work.mkdir(parents=True, exist_ok=True)
    study = work / "study.yaml"
    study.write_text(study_text(n))
    out = work / "results"
    info = machine()
    print(f"running {n**3:,} variants in {work} ...", flush=True)
    r = run(study, out, args.jobs)
    nc, csv = out / "results.nc", out / "summary.csv"
    nc_size = nc.stat().st_size if nc.exists() else 0
    csv_size = csv.stat().st_size if csv.exists() else 0
    n_var = n**3
    failed = "?"
    if csv.exists():
        import pandas as pd

        n_ok = 0
        for part in pd.read_csv(csv, usecols=["status"], chunksize=200_000):
            n_ok += int((part["status"] == "ok").sum())
        failed = str(n_var - n_ok)
    verdict = "PASS" if r["exit"] == 0 and int(r["peak_rss"]) < LIMIT else "FAIL"
    lines = [
        f"# Memory and time of a {n_var:,}-variant summary-only study",
        "",
        f"`python benchmarks/memory_1e6.py{' --per-axis ' + str(n) if n != 100 else ''}"
        f"{' --jobs ' + str(args.jobs) if args.jobs != 1 else ''}`: `crashstudy run` (subprocess, `--jobs {args.jobs}`) "
        f"of the frontal model `studies/models/frontal-9mass.yaml` (9 nodes, 8 springs, 1-D) over "
        f"{n} engine masses (120..210 kg) x {n} rail-loading curve scales (0.7..1.6) x {n} impact speeds "
        "(10..20 m/s), `set: {output: {histories: none}}`.",
        "",
        "| quantity | value |",
        "|---|---|",
        f"| variants | {n_var:,} ({failed} failed) |",
        f"| exit code | {r['exit']} |",
        f"| peak RSS of the process tree | **{mib(int(r['peak_rss']))}** (at {float(r['peak_at']):.0f} s; "
        f"{r['procs']} process(es); psutil polled every 0.1 s, {r['samples']} samples) |",
        f"| requirement | well under 2 GiB: **{verdict}** |",
        f"| wall time | {float(r['wall']):,.0f} s ({n_var / float(r['wall']):,.0f} variants/s, incl. start-up "
        "and writing summary.csv) |",
        f"| results.nc | {mib(nc_size)} ({nc_size / n_var:.0f} bytes/variant) |",
        f"| summary.csv | {mib(csv_size)} ({csv_size / n_var:.0f} bytes/variant) |",
        "",
        "RSS of the process tree during the run (a row per tenth of the wall time):",
        "",
        "| time [s] | RSS |",
        "|---|---|",
        *timeline_rows(r["timeline"], float(r["wall"])),
        "",
        "Machine:",
        "",
        *info,
        "",
        "Output of the run:",
        "",
        "```",
        str(r["stdout"]),
        *([str(r["stderr"])] if r["stderr"] else []),
        "```",
        "",
    ]
    text = "\n".join(lines)
    print(text)
    if args.report != "-":
        Path(args.report).parent.mkdir(parents=True, exist_ok=True)
        Path(args.report).write_text(text)
        print(f"wrote {args.report}")
    if not args.keep and not args.work:
        shutil.rmtree(work, ignore_errors=True)
    return 0 if verdict == "PASS" else 1


if __name__ == "__main__":
    sys.exit(main())
