"""First vs second ``crashstudy simulate`` of a small model: what the compiled-kernel cache buys.

Each repeat gives numba a fresh, empty cache directory (``NUMBA_CACHE_DIR``), runs
``crashstudy simulate`` once ("first": the kernels are compiled and written to that cache) and then
twice more with the same directory ("second", "third": the kernels are loaded from it). Process
wall time from start to exit (results written), under ``/usr/bin/time -v`` for the peak RSS. For
scale: the bare interpreter start (``python -c pass``) and ``import crashstudy.run.runner``.

Run: ``python benchmarks/startup.py [--model studies/models/helicopter-subfloor.yaml] [--repeats 2]``.
Writes ``benchmarks/results/startup.{csv,md}``.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

from common import MODELS, RESULTS, load, machine, machine_md, md_table, median, write_csv  # noqa: E402


def timed(cmd: list[str], env: dict[str, str]) -> tuple[float, float]:
    """(wall s, peak RSS MiB) of a subprocess."""
    timer = ["/usr/bin/time", "-v"] if Path("/usr/bin/time").exists() else []
    t0 = time.perf_counter()
    p = subprocess.run(timer + cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(p.stderr[-2000:])
    m = re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr)
    return wall, int(m.group(1)) / 1024 if m else float("nan")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", type=Path, default=MODELS / "helicopter-subfloor.yaml")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    start_load = load()
    t_start = time.perf_counter()
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory(prefix="startup-") as tmp:
        base_env = dict(os.environ)
        for what, cmd in (
            ("python -c pass", [sys.executable, "-c", "pass"]),
            (
                "python -c 'import crashstudy.run.runner'",
                [sys.executable, "-c", "import crashstudy.run.runner"],
            ),
            (
                "python -c 'import crashstudy.kernel.compiled' (numba)",
                [sys.executable, "-c", "import crashstudy.kernel.compiled"],
            ),
        ):
            walls = [timed(cmd, base_env)[0] for _ in range(3)]
            rows.append(
                {
                    "run": what,
                    "repeat": "median of 3",
                    "wall_s": median(walls),
                    "peak_rss_MiB": float("nan"),
                    "load": load(),
                }
            )
        for r in range(args.repeats):
            cache = Path(tmp) / f"numba-cache-{r}"
            cache.mkdir()
            env = dict(base_env, NUMBA_CACHE_DIR=str(cache))
            for k, label in enumerate(
                ("first (empty cache: compile)", "second (cache written by the first)", "third")
            ):
                out = Path(tmp) / f"out-{r}-{k}"
                wall, rss = timed(
                    [sys.executable, "-m", "crashstudy.cli", "simulate", str(args.model), "-o", str(out)], env
                )
                n_files = sum(1 for _ in cache.rglob("*.nbc"))
                rows.append(
                    {
                        "run": label,
                        "repeat": r,
                        "wall_s": wall,
                        "peak_rss_MiB": rss,
                        "cache_files": n_files,
                        "load": load(),
                    }
                )
                print(f"repeat {r} {label}: {wall:.2f} s, {rss:.0f} MiB (load {load()})", flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    info = machine(start_load)
    write_csv(args.out / "startup.csv", rows, info)
    first = [r["wall_s"] for r in rows if str(r["run"]).startswith("first")]
    second = [r["wall_s"] for r in rows if str(r["run"]).startswith("second")]
    text = (
        "# First vs second `crashstudy simulate` (numba cache)\n\n"
        + machine_md(info)
        + f"- model: {args.model.relative_to(MODELS.parents[1]) if args.model.is_relative_to(MODELS.parents[1]) else args.model}\n"
        + f"- total script time: {time.perf_counter() - t_start:.0f} s\n\n"
        + __doc__.split("\n\n", 1)[1]
        + "\n"
        + f"Median first: {median(first):.2f} s, median second: {median(second):.2f} s "
        f"(x{median(first) / median(second):.1f}).\n\n" + md_table(rows)
    )
    (args.out / "startup.md").write_text(text)
    print(f"wrote {args.out / 'startup.md'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
