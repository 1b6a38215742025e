"""``crashstudy plot`` and ``crashstudy compare``: the commands that read one or two result folders and write
figures or a JUnit file (the figures themselves: :mod:`crashstudy.cli.plot`; the comparison:
:mod:`crashstudy.analysis.compare`). Nothing heavy is imported at module level (cold start).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from crashstudy.cli.columns import arg_problem
from crashstudy.errors import InputError


def register(sub: Any) -> dict[str, Callable[[argparse.Namespace], int]]:
    pl = sub.add_parser("plot", help="write PNG figures of a result folder")
    pl.add_argument("dir", help="result folder (written by run or simulate)")
    pl.add_argument(
        "--kind",
        choices=["history", "force-displacement", "matrix", "pulse"],
        default="history",
        help="history: a quantity over time per item; force-displacement: spring force over crush; "
        "matrix: a summary metric over the study axes; pulse: the SAE J211 filtered acceleration "
        "of the metrics nodes in g over time in ms, beside the raw channel (default history)",
    )
    pl.add_argument(
        "--quantity",
        help="history variable or summary metric (e.g. spring_force, peak_force.cabin); "
        "default: history spring_force; matrix peak_deceleration_g of the node named by a "
        "peak_deceleration_g.<node> key of the study's regression: block, else of the heaviest free "
        "node (the survival room, not the bumper)",
    )
    pl.add_argument("--items", nargs="+", help="nodes or springs to plot (they are part of the file names)")
    pl.add_argument(
        "--time-unit", choices=["s", "ms"], help="unit of the time axis (default the results' own)"
    )
    pl.add_argument("--accel-unit", choices=["g"], help="show accelerations in g (default length/time^2)")
    pl.add_argument(
        "--test", metavar="FILE", help="history: overlay a test curve (CSV time,value or ISO-MME test)"
    )
    pl.add_argument(
        "--channel", metavar="CODE", help="with an ISO-MME --test: its channel code ('?' any one)"
    )
    pl.add_argument("--x", dest="x_axis", help="matrix plot: study axis on the x axis")
    pl.add_argument("--y", dest="y_axis", help="matrix plot: second study axis (heat map)")
    pl.add_argument(
        "--max-variants", type=int, default=50, help="most variants drawn in one figure (default 50)"
    )
    pl.add_argument(
        "--max-points",
        type=int,
        metavar="N",
        help="matrix plot: beyond N variants (default 1000000) the panels are 2-D histograms (variants per "
        "bin, log colour) counted block by block, in memory that does not grow with the study",
    )
    pl.add_argument("-o", "--output", help="folder for the PNGs (default DIR/plots)")
    pl.add_argument("--force", action="store_true", help="write the PNGs even into another result's folder")

    c = sub.add_parser("compare", help="regression check of a result against a baseline")
    c.add_argument("new", help="result folder under test")
    c.add_argument("baseline", help="result folder of the same study to compare with")
    c.add_argument(
        "--rtol",
        type=float,
        help="relative tolerance of every metric the study's regression: block "
        "does not name: |new - old| <= atol + rtol |old| (default 1e-6)",
    )
    c.add_argument("--atol", type=float, help="absolute tolerance, in each metric's own unit (default 0)")
    c.add_argument("--junit", help="write JUnit XML to this file")
    return {"plot": plot, "compare": compare_command}


def plot(args: argparse.Namespace) -> int:
    from crashstudy.cli.plot import plot_command

    out = Path(args.output) if args.output else Path(args.dir) / "plots"
    owner = result_folder_of(out)
    if owner is not None and not args.force and owner.resolve() != Path(args.dir).resolve():
        raise InputError(
            [
                arg_problem(
                    str(out),
                    f"this folder belongs to the results in {owner}, not to "
                    f"{args.dir}; choose another -o or use --force",
                )
            ]
        )
    for path in plot_command(args):
        print(f"wrote {path}")
    return 0


def result_folder_of(path: Path) -> Path | None:
    """The result folder (one holding results.nc or an unfinished run) that ``path`` is or sits directly in."""
    for folder in (path, path.parent):
        if any(
            (folder / n).exists()
            for n in ("results.nc", "results.nc.partial", "results.zarr", "results.zarr.partial")
        ):
            return folder
    return None


def compare_command(args: argparse.Namespace) -> int:
    """``crashstudy compare NEW BASELINE``: prints the values that moved most and a verdict, writes JUnit
    XML if asked; 1 when anything failed, else 0."""
    from crashstudy.analysis.compare import check_tolerance, compare, load_results

    if args.junit and Path(args.junit).name in ("results.nc", "results.nc.partial", "summary.csv"):
        raise InputError([arg_problem(args.junit, "--junit would overwrite a result file; name a .xml file")])
    for name in ("rtol", "atol"):  # bad options are refused before any file is opened
        if getattr(args, name, None) is not None:
            check_tolerance(name, getattr(args, name), f"--{name}")
    new, base = load_results(args.new, "new"), load_results(args.baseline, "baseline")
    try:
        cmp = compare(new, base, rtol=getattr(args, "rtol", None), atol=getattr(args, "atol", None))
    finally:
        new.close()
        base.close()
    print(cmp.report())
    if args.junit:
        cmp.to_junit(args.junit)
        print(f"wrote {args.junit}")
    return 1 if cmp.failed else 0
