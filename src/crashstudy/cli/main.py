"""Command line: parses arguments, calls the runner, prints, and sets exit codes.

Exit codes: 0 success, 1 a check failed or a variant failed, 2 the input is invalid.
"""

from __future__ import annotations

import argparse
import errno
import json
import os
import signal
import sys
from pathlib import Path
from typing import Any

from crashstudy import environment
from crashstudy.cli.process_end import FAST_END, end
from crashstudy.errors import InputError
from crashstudy.safefs import PlantedEntryError

EXIT_OK, EXIT_FAILED, EXIT_INVALID, EXIT_INTERRUPTED = 0, 1, 2, 130

# Modules of further commands, one per command family. Each has ``register(sub)``, which adds its sub-parsers and
# returns ``{command name: handler(args) -> exit code}``; it imports nothing heavy at module level (cold start).
PLUGGED: tuple[str, ...] = ("crashstudy.cli.exchange", "crashstudy.cli.report", "crashstudy.cli.correlate")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="crashstudy", description="Lumped-parameter crash models over design matrices."
    )
    from crashstudy import __version__

    p.add_argument("--version", action="version", version=f"crashstudy {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run every variant of a study")
    r.add_argument("study", help="study file (YAML: name, model, matrix/zip axes; see docs/studies.md)")
    r.add_argument("-o", "--output", help="result folder (default results/<study name>)")
    r.add_argument(
        "--jobs", type=int, default=1, help="worker processes (default 1; the kernel is multi-threaded)"
    )
    r.add_argument(
        "--scheduler", help="Dask scheduler address tcp://HOST:PORT, or 'local' for a LocalCluster"
    )
    r.add_argument(
        "--resume", action="store_true", help="finish an interrupted run (only missing variants run)"
    )
    r.add_argument(
        "--force",
        action="store_true",
        help="recompute everything (default: reuse unchanged variants of this study's earlier results)",
    )
    r.add_argument(
        "--dry-run", action="store_true", help="validate and print the number of variants, run nothing"
    )
    r.add_argument(
        "--progress",
        choices=["auto", "on", "off"],
        default="auto",
        help="progress line (variants done, variants/s, ETA) on stderr: auto = only on a terminal",
    )
    r.add_argument(
        "--store",
        choices=["netcdf", "zarr"],
        default=None,
        help="results.nc (default) or results.zarr (Zarr v3, chunked along variant; see docs/format.md)",
    )
    csv = r.add_mutually_exclusive_group()
    csv.add_argument(
        "--csv",
        dest="csv",
        action="store_true",
        default=None,
        help="also write summary.csv however many variants (default: up to 100,000)",
    )
    csv.add_argument(
        "--no-csv", dest="csv", action="store_false", help="write summary.parquet only (it is always written)"
    )

    v = sub.add_parser("validate", help="check a model or study file and report every problem")
    v.add_argument("file", help="model or study file (YAML); which one it is, is told by its keys")

    s = sub.add_parser("simulate", help="run one model (no matrix)")
    s.add_argument("model", help="model file (YAML: nodes, springs, end_time, ...); a study goes to `run`")
    s.add_argument("-o", "--output", help="result folder (default results/<model name>)")
    s.add_argument(
        "--force",
        action="store_true",
        help="overwrite a folder that holds other results (default: refuse, exit 2)",
    )

    sm = sub.add_parser("summary", help="print the summary table of a result folder")
    sm.add_argument("dir", help="result folder (written by run or simulate)")
    sm.add_argument(
        "--sort",
        help="column to sort by, any column (always shown; e.g. peak_deceleration_g.cabin; a part of "
        "one name will do)",
    )
    sm.add_argument("--ascending", action="store_true", help="sort ascending (default descending)")
    sm.add_argument("--head", type=int, default=30, help="rows to show (0 = all)")
    sm.add_argument(
        "--columns", nargs="+", help="columns to show besides variant and the study axes (substrings match)"
    )
    sm.add_argument("--variant", type=int, help="print this variant's row, every column on a line of its own")
    sm.add_argument(
        "--exceed",
        nargs=2,
        metavar=("COLUMN", "LIMIT"),
        help="print P(COLUMN > LIMIT) over the variants with its exact 95%% interval (Monte Carlo designs)",
    )

    from crashstudy.cli import results_cmd  # plot and compare, in their place in --help

    COMMANDS.update(results_cmd.register(sub))
    from crashstudy.cli.explore import add_parsers, add_search_parsers

    add_parsers(sub)
    add_search_parsers(sub)
    import importlib

    for name in PLUGGED:  # commands that live in a module of their own: register(sub) -> {name: handler}
        COMMANDS.update(importlib.import_module(name).register(sub))
    sc = sub.add_parser("schema", help="print the JSON Schema of model or study files")
    sc.add_argument("kind", choices=["model", "study"], help="which file format")
    return p


def _plain_warnings() -> None:
    """Print crashstudy's own warnings as one line ``warning: ...`` (no source line, no traceback)."""
    import warnings

    from crashstudy.errors import CrashstudyWarning

    default = warnings.showwarning

    def show(message, category, filename, lineno, file=None, line=None):  # type: ignore[no-untyped-def]
        if issubclass(category, CrashstudyWarning):
            print(f"warning: {message}", file=file or sys.stderr)
        else:
            default(message, category, filename, lineno, file, line)

    warnings.showwarning = show


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    code = _command(args)
    if argv is None and args.command in FAST_END:  # the process's own command line: no interpreter teardown
        end(code)
    return code


def _command(args: argparse.Namespace) -> int:
    from crashstudy import interrupt

    interrupt.reset()
    _plain_warnings()
    from crashstudy.kernel.cache import warn_pending

    warn_pending()  # an unsafe NUMBA_CACHE_DIR moved when crashstudy was imported: say so on one line
    signal.signal(signal.SIGTERM, interrupt.request)  # acted on between chunks (crashstudy/interrupt.py)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:  # not when started with SIGINT ignored
        signal.signal(signal.SIGINT, interrupt.request)
    try:
        environment.check()  # a wrong CRASHSTUDY_* value is an input error before any command runs
        return int(COMMANDS[args.command](args))
    except InputError as exc:
        print(f"error: invalid input\n{exc.format()}", file=sys.stderr)
        return EXIT_INVALID
    except KeyboardInterrupt as exc:  # optimize and calibrate say what they kept (interrupt.Stopped)
        note = getattr(exc, "note", "finished variants are kept; continue with --resume")
        print(f"\ninterrupted: {note}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (
        BrokenPipeError
    ):  # the reader of our output stopped (`crashstudy summary DIR | head`): nothing wrong
        os.dup2(
            os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno()
        )  # no second error when stdout is flushed
        return 0
    except (
        FileNotFoundError,
        NotADirectoryError,
        PermissionError,
        IsADirectoryError,
        PlantedEntryError,
    ) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_INVALID
    except OSError as exc:  # disk full, read-only folder: say so plainly
        if exc.errno in _PATH_ERRORS:  # the path itself cannot be used: invalid input, not a failed write
            print(f"error: invalid input\n{_short(exc.filename)}: {_PATH_ERRORS[exc.errno]}", file=sys.stderr)
            return EXIT_INVALID
        print(f"error: cannot write results: {exc}", file=sys.stderr)
        return EXIT_FAILED
    except MemoryError:
        print(
            "error: out of memory: the model or study needs more memory than this machine has (fewer variants "
            "or nodes, or histories: none, need less)",
            file=sys.stderr,
        )
        return EXIT_FAILED
    except RuntimeError as exc:
        from concurrent.futures.process import BrokenProcessPool

        if isinstance(exc, BrokenProcessPool):
            print(
                "error: a worker process died; finished variants are kept: continue with --resume",
                file=sys.stderr,
            )
            return EXIT_FAILED
        if "NetCDF" in str(exc) or "HDF" in str(exc):  # netCDF4 reports a full disk as an HDF error
            print(
                f"error: cannot write results ({exc}): is the disk full or the folder not writable? "
                "Finished variants are kept: continue with --resume",
                file=sys.stderr,
            )
            return EXIT_FAILED
        raise


_PATH_ERRORS = {
    errno.ENAMETOOLONG: "path too long (the system allows 255 bytes per name and 4096 per path)",
    errno.ELOOP: "a loop of symbolic links",
}


def _short(path: object) -> str:
    """A path for a message: printable, at most 100 characters (its start and end)."""
    from crashstudy.errors import printable

    text = printable(os.fsdecode(path) if isinstance(path, (str, bytes)) else str(path), 10_000)
    return text if len(text) <= 100 else f"{text[:48]}...{text[-48:]}"


def _warn(lines: list[str]) -> None:
    for line in lines:
        print(f"warning: {line}", file=sys.stderr)


def _checked(plan: Any) -> None:
    """Print the plan's plausibility warnings; raise its silent mistakes as invalid input (exit 2)."""
    from crashstudy.study.sanity import check_plan

    problems, warnings = check_plan(plan)
    _warn(warnings)
    if problems:
        raise InputError(problems)


def _after_run(res: Any) -> None:
    """Warn when springs went past the ends of their curves, and when the peak deceleration of the
    model's body mass contradicts the result's unit system (the body as the results store it: ``body``)."""
    from crashstudy.results.curve_ends import warnings_of
    from crashstudy.schema.plausible import peak_g_warnings

    with res.stored() as nc:  # as stored: no texts decoded, no xarray (nor pandas, nor dask) imported
        _warn(warnings_of(nc))
        attrs = {k: nc.getncattr(k) for k in nc.ncattrs()}
    body = json.loads(str(attrs.get("body", "{}")))
    node = body.get("node")
    if node is None:
        return
    peak = res.column_peak(f"peak_deceleration_g.{node}")
    if peak is not None:
        _warn(
            peak_g_warnings(
                str(attrs.get("units", "SI")),
                node,
                peak[0],
                peak[1],
                body.get("initial_speeds"),
                bool(body.get("prescribed_motion")),
            )
        )


def _run(args: argparse.Namespace) -> int:
    from crashstudy.run.runner import default_out, run_plan
    from crashstudy.study.plan import load_study

    plan = load_study(args.study)
    _checked(plan)
    print(
        f"study {plan.name}: {plan.n_variants} variants"
        + (" (" + " x ".join(str(s) for s in plan.shape) + ")" if plan.shape else "")
    )
    _work(plan)
    if args.dry_run:
        for ax in plan.axes:
            shown = ", ".join(repr(float(v)) for v in ax.values[:6])
            print(f"  {ax.path}: {len(ax.values)} values [{shown}{', ...' if len(ax.values) > 6 else ''}]")
        return EXIT_OK
    progress = None if args.progress == "auto" else args.progress == "on"
    out = Path(args.output) if args.output else default_out(plan.name)
    rep = run_plan(
        plan,
        out,
        jobs=args.jobs,
        scheduler=args.scheduler,
        resume=args.resume,
        force=args.force,
        progress=progress,
        notes=sys.stderr,
        csv=args.csv,
        store=args.store,
    )
    reused = f", {rep.n_reused} unchanged variants reused" if rep.n_reused else ""
    print(
        f"wrote {rep.results.path} and {_tables(rep.results.dir)} ({rep.n_computed} variants computed in "
        f"{rep.seconds:.1f} s{reused})"
    )
    _after_run(rep.results)
    if rep.n_failed:
        print(
            f"{rep.n_failed} of {rep.n_variants} variants failed (see status / failure_reason)",
            file=sys.stderr,
        )
        return EXIT_FAILED
    return EXIT_OK


def _tables(folder: Path) -> str:
    return " and ".join(n for n in ("summary.parquet", "summary.csv") if (folder / n).exists())


def _validate(args: argparse.Namespace) -> int:
    from crashstudy.schema import file_kind, parse_model
    from crashstudy.schema.yamlio import load_yaml
    from crashstudy.study.plan import load_study

    doc = load_yaml(args.file)
    if file_kind(doc.data) == "study":
        plan = load_study(args.file)
        _checked(plan)
        print(f"{args.file}: valid study ({plan.n_variants} variants)")
        _work(plan)
    else:
        from crashstudy.study.plan import plan_from_model

        lm = parse_model(doc)
        plan = plan_from_model(lm)
        if (
            plan.topology.time_step_mode == "dt"
        ):  # the runner (pandas, xarray, netCDF4: 0.5 s) only for a fixed dt
            from crashstudy.run.runner import refuse_fixed_dt

            refuse_fixed_dt(plan, doc)
        _checked(plan)
        m = lm.model
        print(
            f"{args.file}: valid model ({len(m.nodes)} nodes, {len(m.springs)} springs, "
            f"{len(next(iter(m.nodes.values())).position)}-D)"
        )
        _work(plan)
    return EXIT_OK


def _work(plan: Any) -> None:
    """Say how long a run of ``plan`` takes when that is long (its refusal beyond the limit is an input error)."""
    from crashstudy.study.work import WORK_ENV, WORK_RATE, WORK_REPORT, format_duration, max_work

    if plan.work >= WORK_REPORT:
        print(
            f"  about {plan.work:.3g} element-steps (springs x time steps, summed over the variants): about "
            f"{format_duration(plan.work / WORK_RATE)} at {WORK_RATE:.0e} a second; the limit is {max_work():.3g} "
            f"({WORK_ENV})"
        )


def _simulate(args: argparse.Namespace) -> int:
    from crashstudy.run.runner import simulate_report

    rep = simulate_report(
        args.model, args.output, force=args.force, notes=sys.stderr, warn=lambda w: _warn([w])
    )
    s = rep.results.summary.iloc[0]
    print(f"wrote {rep.results.path} and {_tables(rep.results.dir)}")
    print(
        f"  status {s['status']}  dt {s['dt']:.4g}  energy_error {s['energy_error']:.2e}  ({s['dt_control']})"
    )
    _after_run(rep.results)
    if s["status"] != "ok":
        print(f"  failed: {s['failure_reason']}", file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK


def _summary(args: argparse.Namespace) -> int:
    from crashstudy.cli.explore import summary_command  # read block by block (issue 19)

    return summary_command(args)


def _schema(args: argparse.Namespace) -> int:
    import json

    from crashstudy.schema.model import Model
    from crashstudy.schema.study import Study

    cls = Model if args.kind == "model" else Study
    print(json.dumps(cls.model_json_schema(), indent=2))
    return EXIT_OK


def _sensitivity(args: argparse.Namespace) -> int:
    from crashstudy.cli.explore import sensitivity

    return sensitivity(args)


def _optimize(args: argparse.Namespace) -> int:
    from crashstudy.cli.explore import optimize_command

    return optimize_command(args)


def _calibrate(args: argparse.Namespace) -> int:
    from crashstudy.cli.explore import calibrate_command

    return calibrate_command(args)


COMMANDS = {
    "run": _run,
    "validate": _validate,
    "simulate": _simulate,
    "summary": _summary,
    "schema": _schema,
    "sensitivity": _sensitivity,
    "optimize": _optimize,
    "calibrate": _calibrate,
}

if __name__ == "__main__":
    sys.exit(main())
