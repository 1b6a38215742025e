"""Result files before and after the compact storage of issue 9: size, end-to-end time, peak memory.

The same study (the 2-spring model of ``small_models.py``, histories none) is run by two versions of
crashstudy side by side in this script: the commit before (``--before``, default 48eb447, exported
with ``git archive`` into a temporary folder and put first on ``PYTHONPATH``) and the working tree.
Each version first runs a small warm-up study (its kernels compiled and cached), then the timed
``crashstudy run`` (a fresh output folder), under ``/usr/bin/time -v`` for the peak RSS. Sizes of
``results.nc``, ``summary.csv`` and ``summary.parquet`` as written.

Run: ``python benchmarks/results_size.py [--variants 100000 1000000] [--before 48eb447]``.
Writes ``benchmarks/results/results_size.{csv,md}``.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import RESULTS, ROOT, load, machine, machine_md, md_table, write_csv  # noqa: E402
from small_models import model_yaml, study_yaml  # noqa: E402


def export(commit: str, into: Path) -> Path:
    """``git archive`` of ``commit`` unpacked into ``into``; returns its ``src`` folder."""
    into.mkdir(parents=True, exist_ok=True)
    tar = into / "src.tar"
    subprocess.run(["git", "archive", "-o", str(tar), commit, "src"], cwd=ROOT, check=True)
    with tarfile.open(tar) as t:
        t.extractall(into, filter="data")
    return into / "src"


def run(src: Path, study: Path, out: Path, env: dict[str, str]) -> dict[str, Any]:
    cmd = [
        "/usr/bin/time",
        "-v",
        sys.executable,
        "-m",
        "crashstudy.cli",
        "run",
        str(study),
        "-o",
        str(out),
        "--progress",
        "off",
    ]
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=dict(env, PYTHONPATH=str(src)), capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(p.stderr[-3000:])
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr)
    sizes = {
        f"{n}_MB": (out / n).stat().st_size / 1e6 if (out / n).exists() else float("nan")
        for n in ("results.nc", "summary.csv", "summary.parquet")
    }
    return {"wall_s": wall, "peak_rss_MiB": int(m.group(1)) / 1024 if m else float("nan"), **sizes}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variants", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--before", default="48eb447")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    start_load = load()
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="results-size-") as tmp:
        d = Path(tmp)
        trees = {
            f"before ({args.before})": export(args.before, d / "before"),
            "after (working tree)": ROOT / "src",
        }
        model = d / "model.yaml"
        model.write_text(model_yaml(2, 0.075))
        (d / "warm.yaml").write_text(study_yaml(2, 1000, model))
        env = {k: v for k, v in os.environ.items() if k not in ("CRASHSTUDY_KERNEL", "PYTHONPATH")}
        for label, src in trees.items():
            run(src, d / "warm.yaml", d / f"warm-{label[:5]}", env)
            for n in args.variants:
                study = d / f"s{n}.yaml"
                study.write_text(study_yaml(2, n, model))
                r = run(src, study, d / f"out-{label[:5]}-{n}", env)
                rows.append(
                    {
                        "version": label,
                        "variants": n,
                        **r,
                        "us_per_variant": 1e6 * r["wall_s"] / n,
                        "load": load(),
                    }
                )
                print(rows[-1], flush=True)
    info = machine(start_load)
    write_csv(args.out / "results_size.csv", rows, info)
    text = (
        "# Result files before and after (2-spring model, histories none)\n\n"
        + machine_md(info)
        + "\n"
        + __doc__.split("\n\n", 1)[1]
        + "\n"
        + md_table(rows)
    )
    (args.out / "results_size.md").write_text(text)
    print(f"wrote {args.out / 'results_size.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
