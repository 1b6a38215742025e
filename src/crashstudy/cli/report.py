"""``crashstudy report DIR``: one self-contained HTML page of a result folder (SPEC 8d; docs/report.md).

Only the command line lives here (arguments, output policy, exit codes); the page is built by
:mod:`crashstudy.analysis.report`. Nothing heavy is imported at module level (cold start).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

EXIT_OK = 0
RESULT_FILES = ("results.nc", "results.nc.partial", "summary.parquet", "summary.csv", "manifest.json")


def register(sub: Any) -> dict[str, Callable[[argparse.Namespace], int]]:
    rp = sub.add_parser("report", help="one self-contained HTML report of a result folder (opens offline)")
    rp.add_argument("dir", help="result folder (written by run, simulate, optimize or calibrate)")
    rp.add_argument("-o", "--output", help="the HTML file to write (default DIR/report.html)")
    rp.add_argument(
        "--variants",
        metavar="SEL",
        help="variants whose histories are drawn: numbers, ranges A-B and the names worst, best, "
        "baseline, comma-separated (default worst,best,baseline)",
    )
    rp.add_argument(
        "--responses",
        nargs="+",
        metavar="COLUMN",
        help="summary columns drawn against the axes (default: the crash node's peak deceleration "
        "in g and the crash criteria)",
    )
    rp.add_argument(
        "--limits",
        nargs="+",
        metavar="COLUMN<=NUMBER",
        default=[],
        help="your own pass/fail checks on summary columns (as optimize: constraints), drawn with the "
        "usual criteria limits and the study's optimize: constraints",
    )
    rp.add_argument(
        "--test",
        metavar="CSV",
        help="a test curve to draw over the histories: CSV with columns time, value (time in s, "
        "value in the units of the drawn history)",
    )
    rp.add_argument("--force", action="store_true", help="replace an existing report file")
    return {"report": report_command}


def _problem(where: str, field: str, message: str) -> Any:
    from crashstudy.errors import InputError, Problem

    return InputError([Problem(where, None, field, message)])


def output_path(args: argparse.Namespace) -> Path:
    """Where the report goes, after the output policy: never over an existing file without ``--force``,
    never over one of a result folder's own files, never into another result folder without ``--force``."""
    from crashstudy.cli.results_cmd import result_folder_of

    out = Path(args.output) if args.output else Path(args.dir) / "report.html"
    if out.name in RESULT_FILES:
        raise _problem(str(out), "-o", "this name is one of a result folder's own files; name an .html file")
    if os.path.lexists(out) and os.path.isdir(out):
        raise _problem(str(out), "-o", "this is a folder; name the .html file to write")
    if os.path.lexists(out) and not args.force:
        raise _problem(str(out), "-o", "the file exists; use --force to replace it or choose another -o")
    owner = result_folder_of(out.parent) if out.parent != Path(args.dir) else None
    if owner is not None and not args.force and owner.resolve() != Path(args.dir).resolve():
        raise _problem(
            str(out),
            "-o",
            f"this folder belongs to the results in {owner}, not to {args.dir}; "
            "choose another -o or use --force",
        )
    return out


def report_command(args: argparse.Namespace) -> int:
    import time

    from crashstudy.analysis.report import build_report
    from crashstudy.results.reader import open_results
    from crashstudy.safefs import write_text

    t0 = time.perf_counter()
    out = output_path(args)
    test = None
    if args.test:
        from crashstudy.analysis.optimization import DataFileError, read_data

        try:
            test = read_data(Path(args.test))
        except DataFileError as exc:
            raise _problem(args.test, "--test", str(exc)) from None
    try:
        res = open_results(args.dir)
    except FileNotFoundError as exc:
        raise _problem(str(args.dir), "", str(exc)) from None
    try:
        text = build_report(res, args.variants, args.responses, test, where=str(args.dir), limits=args.limits)
    finally:
        res.close()
    write_text(out, text)
    size = os.stat(out).st_size
    print(f"wrote {out} ({size / 2**20:.1f} MiB, {time.perf_counter() - t0:.1f} s)")
    return EXIT_OK
