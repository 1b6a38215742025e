"""Issue 19: the 2-spring study at 10^5, 10^6, ... variants, each store, in-process and on a LocalCluster.

The model is ``benchmarks/matrix.py``'s 2-spring chain (two ``nonlinear_elastic`` springs, 1-D) at the short
end time (0.0086 s, 86 steps), histories none; the study crosses a masses of m1 with n / a masses
of m2 (a = 100, from 10^8 variants n / 10^5: a study file holds at most 10^6 values). Each cell runs ``crashstudy run`` as a subprocess twice into the same folder (a fresh run, then a
re-run that reuses every variant), while psutil polls the resident set size of the command and of every
process it started (the Dask scheduler and workers of ``--scheduler local``) every 0.1 s. Recorded: wall
time, time per variant, the peak RSS of each process (the client's and the largest other's), the bytes
the result folder holds. The kernel is compiled once before the first cell (its cache is reused).

The ``--scheduler local`` cells run the command through this script (``--as-client``), which counts the
bytes of every result the Dask workers send back to the client (each result pickled, as Dask sends a
Python object; its arrays travel as frames of the same size): with ``--store netcdf`` every chunk's
arrays (the client writes), with ``--store zarr`` a receipt per region (the workers write the store).
The other processes of such a run are the two worker processes (the scheduler and the nannies run in
the client process).

Usage::

    python benchmarks/scale.py                        # 10^5 and 10^6, netcdf and zarr in-process
    python benchmarks/scale.py --sizes 1e5 --dask     # also --scheduler local with each of --dask-stores

Options: ``--sizes`` (comma list), ``--stores`` (netcdf,zarr; ``none``: no in-process cell), ``--dask``,
``--dask-stores`` (default zarr), ``--runs`` (fresh,re-run), ``--work DIR``, ``--report FILE`` (default benchmarks/results/scale.md;
``-`` prints only), ``--append TITLE`` (add the table to the report as a section ``TITLE``).
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
    a = (
        max(100, n // 100_000) if n >= 100 else 1
    )  # <= 10^5 listed values an axis (a study lists at most 10^6)
    m2 = [round(float(v), 9) for v in np.linspace(1.0, 3.0, n // a)]
    m1 = [round(float(v), 9) for v in np.linspace(0.5, 2.0, a)]
    study = folder / "study.yaml"
    study.write_text(
        f"name: scale-{n}\nmodel: model.yaml\nmatrix:\n  nodes.m2.mass: {m2}\n  nodes.m1.mass: {m1}\n"
    )
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
    return {
        "exit": proc.returncode,
        "wall": wall,
        "client": client,
        "others": sorted(peaks.values(), reverse=True),
        "stdout": out.strip(),
        "stderr": err.strip()[-1500:],
    }


RECEIVED = "client received: "


def as_client(argv: list[str]) -> int:
    """``crashstudy`` with ``argv``, counting what the Dask backend's results weigh as they reach this
    process; prints ``client received: {bytes, results}`` (JSON) to stderr at the end."""
    import json
    import pickle

    import crashstudy.run.backends as backends
    from crashstudy.cli.main import main as cli

    real = backends.make_backend
    seen = {"bytes": 0, "results": 0, "largest": 0}

    class Counting:
        def __init__(self, inner: Any) -> None:
            self.inner = inner

        def __getattr__(self, name: str) -> Any:
            return getattr(self.inner, name)

        def imap_unordered(self, fn: Any, tasks: Any) -> Any:
            for res in self.inner.imap_unordered(fn, tasks):
                n = len(pickle.dumps(res, protocol=5))
                seen["bytes"] += n
                seen["results"] += 1
                seen["largest"] = max(seen["largest"], n)
                yield res

    backends.make_backend = lambda *a, **k: Counting(real(*a, **k))  # type: ignore[assignment]
    code = cli(argv)
    print(RECEIVED + json.dumps(seen), file=sys.stderr)
    return int(code or 0)


def received(stderr: str) -> dict[str, int]:
    import json

    lines = [ln for ln in stderr.splitlines() if ln.startswith(RECEIVED)]
    return json.loads(lines[-1][len(RECEIVED) :]) if lines else {}


def folder_bytes(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file() and not f.is_symlink())


def cell(
    work: Path, n: int, store: str, dask: bool, runs: tuple[str, ...] = ("fresh", "re-run")
) -> list[dict[str, Any]]:
    study = write_study(work / f"n{n}", n)
    out = work / f"n{n}" / f"out-{store}{'-dask' if dask else ''}"
    cli = [sys.executable, __file__, "--as-client"] if dask else [sys.executable, "-m", "crashstudy.cli"]
    cmd = (
        cli
        + ["run", str(study), "-o", str(out), "--progress", "off", "--store", store]
        + (["--scheduler", "local"] if dask else [])
    )
    rows = []
    for kind in runs:
        r = watch(cmd + (["--force"] if kind == "fresh" else []), study.parent)
        if r["exit"] != 0:
            print(r["stderr"], file=sys.stderr)
        others = r["others"]
        got = received(r["stderr"])
        rows.append(
            {
                "variants": n,
                "store": store,
                "where": "LocalCluster(2)" if dask else "in-process",
                "run": kind,
                "wall [s]": round(r["wall"], 1),
                "per variant [us]": round(1e6 * r["wall"] / n, 2),
                "client peak RSS [MiB]": round(r["client"] / 2**20),
                "other processes' peak RSS [MiB]": ", ".join(str(round(o / 2**20)) for o in others[:3])
                or "-",
                "bytes written [MB]": round(folder_bytes(out) / 1e6, 1),
                "client received [MB]": round(got["bytes"] / 1e6, 3) if got else "-",
                "per result [kB] (largest)": (
                    f"{got['bytes'] / max(got['results'], 1) / 1e3:.1f} ({got['largest'] / 1e3:.1f})"
                )
                if got.get("results")
                else "-",
                "load": load(),
                "exit": r["exit"],
            }
        )
        print(rows[-1], flush=True)
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="1e5,1e6")
    ap.add_argument("--stores", default="netcdf,zarr")
    ap.add_argument(
        "--dask", action="store_true", help="also run --scheduler local with each of --dask-stores"
    )
    ap.add_argument("--dask-stores", default="zarr")
    ap.add_argument(
        "--append", default="", metavar="TITLE", help="add the table to the report as a section TITLE"
    )
    ap.add_argument("--runs", default="fresh,re-run", help="which runs of each cell (fresh, re-run)")
    ap.add_argument("--work", type=Path, default=None)
    ap.add_argument("--report", default=str(REPORT))
    args = ap.parse_args(argv)
    start = load()
    runs = tuple(args.runs.split(","))
    work = args.work or Path(tempfile.mkdtemp(prefix="crashstudy-scale-"))
    warm = write_study(work / "warm", 100)  # compile (or load) the kernel once, outside the figures
    subprocess.run(
        [
            sys.executable,
            "-m",
            "crashstudy.cli",
            "run",
            str(warm),
            "-o",
            str(warm.parent / "out"),
            "--progress",
            "off",
            "--force",
        ],
        cwd=warm.parent,
        capture_output=True,
        check=False,
    )
    rows: list[dict[str, Any]] = []
    for size in (int(float(s)) for s in args.sizes.split(",")):
        for store in args.stores.split(","):
            if store != "none":
                rows += cell(work, size, store, False, runs)
        if args.dask:
            for store in args.dask_stores.split(","):
                rows += cell(work, size, store, True, runs)
    head = f"\n## {args.append}\n\n" if args.append else "# Scale: the 2-spring study (issue 19)\n\n"
    text = (
        head
        + machine_md(machine(start))
        + "\n\n"
        + "Command: `python benchmarks/scale.py "
        + " ".join(argv or sys.argv[1:])
        + "`; each cell runs "
        "`crashstudy run` fresh (`--force`) and then again (every variant reused); `load` is the 1-min load "
        "average after the run (the machine is shared: wall times are not comparable between rows).\n\n"
        + md_table(rows)
        + "\n"
    )
    if args.report == "-":
        print(text)
    else:
        old = Path(args.report).read_text() if args.append and Path(args.report).exists() else ""
        Path(args.report).write_text(old + text)
        print(f"wrote {args.report}")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("CRASHSTUDY_BACKGROUND_COMPILE", "0")
    if sys.argv[1:2] == ["--as-client"]:
        raise SystemExit(as_client(sys.argv[2:]))
    raise SystemExit(main())
