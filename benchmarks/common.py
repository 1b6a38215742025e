"""Shared helpers of the benchmark scripts: the machine record, load average, result files.

Benchmarks run on demand (never in the test suite). The machine may be shared, so every result
file records the core count, the CPU model and the load average at start and end, and the scripts
measure medians of repeats with the compared runs interleaved in the same process.
"""

from __future__ import annotations

import csv
import datetime as _dt
import os
import platform
import statistics
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
MODELS = ROOT / "studies" / "models"
FRONTAL = MODELS / "frontal-9mass.yaml"


def _run(cmd: list[str]) -> str:
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=30, cwd=ROOT).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def cpu_model() -> str:
    for line in _run(["lscpu"]).splitlines():
        if line.startswith("Model name:"):
            return line.split(":", 1)[1].strip()
    return platform.processor() or "unknown"


def load() -> str:
    """The 1/5/15-minute load averages as text."""
    return " / ".join(f"{x:.2f}" for x in os.getloadavg())


def machine(start_load: str) -> dict[str, str]:
    """What the numbers were measured on (call at the end; ``start_load`` from :func:`load` at start)."""
    import numba
    import numpy
    import scipy

    import crashstudy

    commit = _run(["git", "rev-parse", "--short", "HEAD"])
    src = Path(crashstudy.__file__).resolve().parent
    if src.is_relative_to(ROOT):
        dirty = _run(["git", "status", "--porcelain", "--", "src"])
        measured = commit + (" (src/ has uncommitted edits)" if dirty else "")
    else:  # a snapshot (git archive of a commit) put first on PYTHONPATH
        stamp = src.parents[1] / "COMMIT"
        snap = stamp.read_text().strip() if stamp.exists() else "unknown commit"
        measured = f"snapshot of commit {snap} (git archive; the repository HEAD was {commit})"
    return {
        "date": _dt.datetime.now().isoformat(timespec="seconds"),
        "os.cpu_count()": str(os.cpu_count()),
        "CPU model (lscpu)": cpu_model(),
        "host (boot time; LLVM CPU name and vector features)": host(),
        "load average at start (1/5/15 min)": start_load,
        "load average at end (1/5/15 min)": load(),
        "python / numpy / numba / scipy": f"{platform.python_version()} / {numpy.__version__} / "
        f"{numba.__version__} / {scipy.__version__}",
        "crashstudy imported from": str(src),
        "crashstudy code measured": measured,
        "command": " ".join([Path(sys.executable).name, *sys.argv]),
    }


def host() -> str:
    """The machine's boot time and the CPU LLVM compiles for (its name and widest vector features):
    a figure that moved by a factor between two dates on a new VM of the same "CPU model" shows it here
    (the frontal throughput of 11-25 against 11-26: benchmarks/results/throughput_question_speed25.md)."""
    import llvmlite.binding as ll

    boot = _run(["uptime", "-s"]) or "unknown"
    feats = ll.get_host_cpu_features()
    vec = [f for f in ("avx512f", "avx2", "avx", "fma", "sse4.2") if feats.get(f)]
    return f"booted {boot}; {ll.get_host_cpu_name()} ({' '.join(vec) or 'no AVX'})"


def machine_md(info: dict[str, str]) -> str:
    return "\n".join(f"- {k}: {v}" for k, v in info.items()) + "\n"


def median(xs: Sequence[float]) -> float:
    return float(statistics.median(xs))


def write_csv(path: Path, rows: list[dict[str, Any]], info: dict[str, str]) -> None:
    """Rows as CSV; every row also carries the machine record ``info`` (cores, CPU model, load at start
    and end), so the file stands on its own."""
    path.parent.mkdir(parents=True, exist_ok=True)
    keep = (
        "os.cpu_count()",
        "CPU model (lscpu)",
        "load average at start (1/5/15 min)",
        "load average at end (1/5/15 min)",
        "crashstudy code measured",
    )
    rows = [{**r, **{f"machine: {k}": info[k] for k in keep if k in info}} for r in rows]
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)


def md_table(rows: list[dict[str, Any]], cols: list[str] | None = None) -> str:
    """A Markdown table of ``rows`` (floats in 3 significant digits)."""
    if not rows:
        return "(no rows)\n"
    if cols is None:
        cols = []
        for r in rows:
            cols += [k for k in r if k not in cols]

    def fmt(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.3g}"
        return str(v)

    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    out += ["| " + " | ".join(fmt(r.get(c, "")) for c in cols) + " |" for r in rows]
    return "\n".join(out) + "\n"


def wait_for_kernels(plan: Any, timeout: float = 600.0) -> None:
    """Until the generic kernel and ``plan``'s generated kernel are compiled (numba's disk cache): what a
    background compile started by an earlier run leaves, compiled here when no other process holds the lock.
    A warm cell measured while that compile still runs would wait for it, or share the cores with it."""
    import time

    from crashstudy.arrays.batch import build_batch
    from crashstudy.kernel import choice, generated

    sample, _ = build_batch(plan.topology, plan.params(0, 1), plan.interval)
    hist, vary = plan.topology.histories, plan.varying_curves
    # a model over the generated kernel's cap (the grid's 1179 springs) runs the generic kernel only
    kernels = ("generic", "generated") if generated.unsupported(sample) is None else ("generic",)
    deadline = time.time() + timeout
    while (
        not (
            choice.generic_ready()
            and ("generated" not in kernels or choice.generated_ready(sample, hist, vary))
        )
        and time.time() < deadline
    ):
        choice.compile_foreground(kernels, sample, hist, vary, lambda: None)
        time.sleep(1.0)  # another process held the lock: its compile ends, or the next round compiles
