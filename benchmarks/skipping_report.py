"""The skipping benchmark's report: the machine and source measured, the notes, the Markdown table and
the figure.

Part of benchmarks/skipping.py (what skipping costs and saves, issue 4, item 3), which describes the
comparisons and how they are timed."""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import platform
import subprocess
from pathlib import Path

import numpy as np

from skipping_measure import ROOT, Case, Row

# ---------------------------------------------------------------------------------------------- report


def machine(note: str = "") -> list[str]:
    try:
        lscpu = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
        model = next(
            (ln.split(":", 1)[1].strip() for ln in lscpu.splitlines() if ln.startswith("Model name")), "?"
        )
    except OSError:
        model = platform.processor() or "?"
    import numba

    import crashstudy

    pkg = Path(crashstudy.__file__).resolve().parent
    if pkg.is_relative_to(ROOT):
        git = ["git", "-C", str(ROOT)]
        head = subprocess.run(
            [*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        ).stdout.strip()
        dirty = subprocess.run(
            [*git, "status", "--porcelain", "src"], capture_output=True, text=True
        ).stdout.split()
        changed = [f for f in dirty if f.startswith("src/")]
        source = f"this checkout at {head}" + (
            f", with uncommitted changes in {', '.join(changed)}" if changed else ""
        )
    else:
        source = str(pkg)
    if note:
        source += f" ({note})"
    return [
        f"- crashstudy source: {source}",
        f"- CPU: {model}, {os.cpu_count()} cores (lscpu); shared with other users' runs",
        f"- Python {platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}, "
        f"{platform.system()} {platform.release()}",
        f"- date {_dt.datetime.now().isoformat(timespec='seconds')}",
    ]


NOTES = [
    "Notes (what each skip is: [docs/benchmarks-skipping.md](../../docs/benchmarks-skipping.md)):",
    "",
    "- Geometry: both drawings are the frontal model drawn twice as long. As drawn in the file, the crash box is "
    "compressed past zero length (1-D: the curve's bottoming); in 2-D it turns inside out without being flagged.",
    "- Termination: the kernel runs a block of 256 variants until its last variant stops; stopped variants are "
    "still computed under the masks, so only whole blocks that stop save time.",
    "- Identical variants: the gain is total CPU time for the same 10^4 results; most of what remains is "
    "`np.unique` over the parameter columns.",
]


def write_report(
    rows: list[Row],
    log: list[str],
    args: argparse.Namespace,
    seconds: float,
    load0: str,
    load1: str,
    png: str | None,
) -> str:
    lines = [
        "# Skipping what a scene does not need: measured gains",
        "",
        "Written by `python benchmarks/skipping.py` "
        f"(`--variants {args.variants} --repeats {args.repeats} --cold-repeats {args.cold_repeats}`). "
        "Each comparison toggles one feature on the same physics; its cases run side by side in one process, "
        f"interleaved, after a warm-up; medians of {args.repeats} repeats (first-call processes: "
        f"{args.cold_repeats}). CPU time is `time.process_time()` with the kernel on one thread "
        "(`set_threads(1)`); one element-step = one spring advanced one step for one variant, counted "
        "from the steps actually computed (`t_end / dt`). Gain = baseline / with-skip (per element-step "
        "where the element-steps are the same; total time where the skip removes steps or variants).",
        "",
        "## Machine",
        "",
        *machine(args.source_note),
        f"- load average (1/5/15 min) at start {load0}, at end {load1}",
        f"- total run time {seconds:.0f} s",
        "",
        "## Table",
        "",
        "| feature | baseline | with skip | gain | error check |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(f"| {r.feature} | {r.baseline} | {r.skip} | {r.gain} | {r.check} |")
    lines += ["", *NOTES]
    lines += [
        "",
        "## Details (medians; load average before -> after each comparison)",
        "",
        "```",
        *log,
        "```",
    ]
    if png:
        lines += ["", f"![time per element-step]({png})"]
    return "\n".join(lines) + "\n"


def plot(all_cases: list[tuple[str, list[Case]]], path: Path) -> bool:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    groups = [(g, cs) for g, cs in all_cases if cs]
    fig, axes = plt.subplots(1, len(groups), figsize=(3.2 * len(groups), 3.6), squeeze=False)
    for ax, (g, cs) in zip(axes[0], groups, strict=True):
        total = g.startswith("5.")  # termination removes steps: compare the whole run's CPU time
        vals = [c.cpu_med if total else c.ns_per for c in cs]
        ax.bar(range(len(cs)), vals, color="tab:blue")
        ax.set_xticks(range(len(cs)), [c.name for c in cs], rotation=30, ha="right", fontsize=7)
        ax.set_title(g, fontsize=9)
        ax.set_ylabel("CPU s (median)" if total else "CPU ns per element-step (median)", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True
