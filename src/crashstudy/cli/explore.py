"""Command line of design exploration: ``crashstudy sensitivity``, ``optimize`` and ``calibrate`` (parsing,
printing, exit codes; the numbers come from :mod:`crashstudy.analysis`). ``crashstudy summary`` (and its
``--exceed``) lives in :mod:`crashstudy.cli.summary_table`, re-exported here."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from crashstudy.cli.summary_table import (  # noqa: F401 - cli/main.py and tests import the summary command here
    EXIT_OK,
    _number,
    _top_rows,
    exceed_text,
    summary_command,
)
from crashstudy.errors import InputError, Problem
from crashstudy.interrupt import Stopped
from crashstudy.safefs import replacing, replacing_path, write_all, write_text

EXIT_INVALID = 2


def add_parsers(sub: Any) -> None:
    se = sub.add_parser(
        "sensitivity", help="sensitivity of a summary column to the study axes (sensitivity.csv)"
    )
    se.add_argument("dir", help="result folder of a study")
    se.add_argument(
        "--metric",
        required=True,
        help="summary column, e.g. peak_deceleration_g.cabin (a part of one name will do)",
    )
    se.add_argument(
        "--method",
        choices=["correlation", "sobol", "morris"],
        default="correlation",
        help="correlation (any study; Spearman and Pearson), sobol (design method saltelli: S1, ST), "
        "morris (design method morris: mu_star, sigma); default correlation",
    )
    se.add_argument(
        "--history",
        metavar="QUANTITY",
        help="also: Spearman correlation of this history (e.g. spring_force) with each axis at every "
        "sample -> sensitivity_<quantity>.nc and .png",
    )
    se.add_argument("--item", help="with --history: the spring or node (default the first)")


def sensitivity(args: argparse.Namespace) -> int:
    from crashstudy.analysis.correlation import correlation_table
    from crashstudy.analysis.sensitivity import factor_columns, indices
    from crashstudy.cli.columns import match_column as _match_column
    from crashstudy.results.store import open_results

    res = open_results(args.dir)
    try:
        with res.raw_dataset as raw:
            attrs = dict(raw.attrs)
        names = res.summary_names()
        metric = _match_column(args.dir, args.metric, names)
        axes = [a for a in json.loads(attrs.get("crashstudy_axes", "[]")) if a in names]
        # only the columns the indices use (a 10^8-variant summary is ~25 GB whole, these ~8 B each per variant)
        columns = list(dict.fromkeys(["variant", "status", *axes, metric]))
        try:
            if args.method == "correlation":  # block by block: bounded memory (analysis/correlation.py)
                factors = factor_columns(
                    attrs, [str(a) for a in json.loads(attrs.get("crashstudy_axes", "[]"))]
                )
                table = correlation_table(lambda: res.summary_batches(columns), factors, metric)
            else:  # SALib's estimators need their columns whole
                table = indices(res.summary_columns(columns), attrs, metric, args.method)
        except ValueError as exc:
            raise InputError([Problem(args.dir, None, "--method", str(exc))]) from None
        if args.history:
            _over_time(res, args)
    finally:
        res.close()
    out = Path(args.dir) / "sensitivity.csv"
    write_text(out, table.to_csv(index=False))
    import pandas as pd

    with pd.option_context("display.max_rows", None, "display.width", 120, "display.max_colwidth", 60):
        print(table.drop(columns=["metric"]).to_string(index=False))
    for note in sorted({n for n in table["note"] if n}):
        print(f"note: {note}", file=sys.stderr)
    print(f"wrote {out}")
    return EXIT_OK


def _over_time(res: Any, args: argparse.Namespace) -> None:
    from crashstudy.analysis.sensitivity import over_time

    ds = res.dataset
    if args.history not in ds:
        kept = [v for v in ds.data_vars if "time" in ds[v].dims]
        raise InputError(
            [
                Problem(
                    args.dir,
                    None,
                    "--history",
                    f"no history {args.history!r} in the results; "
                    f"kept: {kept or 'none (output.histories: none)'}",
                )
            ]
        )
    try:
        da = over_time(ds, args.history, args.item)
    except ValueError as exc:
        raise InputError([Problem(args.dir, None, "--item", str(exc))]) from None
    stem = Path(args.dir) / f"sensitivity_{args.history}"
    with replacing_path(stem.with_suffix(".nc")) as tmp:
        da.to_netcdf(tmp)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5))
    t = da["time"].values
    for a in da["axis_path"].values:
        ax.plot(t, da.sel(axis_path=a).values, label=str(a))
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_ylim(-1.05, 1.05)
    ax.set_xlabel(f"time [{ds['time'].attrs.get('units', '')}]")
    ax.set_ylabel("Spearman correlation [1]")
    ax.set_title(f"{da.attrs['long_name']}")
    ax.legend(loc="best", fontsize=8)
    with replacing(
        stem.with_suffix(".png"), mode="wb"
    ) as fh:  # a link there is replaced, never written through
        fig.savefig(fh, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    print(f"wrote {stem.with_suffix('.nc')} and {stem.with_suffix('.png')}")


def add_search_parsers(sub: Any) -> None:
    op = sub.add_parser(
        "optimize", help="run a study's optimize: block (optimum.yaml, history.csv, its results)"
    )
    op.add_argument("study", help="study file with an optimize: block")
    op.add_argument("-o", "--output", help="result folder (default results/<study name>)")
    op.add_argument(
        "--force",
        action="store_true",
        help="overwrite a folder that holds another study's results or an unfinished run (default: refuse)",
    )
    ca = sub.add_parser(
        "calibrate", help="run a study's calibrate: block (calibrated.yaml, a data-vs-fit plot)"
    )
    ca.add_argument("study", help="study file with a calibrate: block")
    ca.add_argument("-o", "--output", help="result folder (default results/<study name>)")
    ca.add_argument(
        "--force",
        action="store_true",
        help="overwrite a folder that holds another study's results or an unfinished run (default: refuse)",
    )


def _study_dict(path: str, block: str) -> tuple[dict[str, Any], Path]:
    """The validated study as plain data (model path absolute) and its folder."""
    from crashstudy.schema.yamlio import load_yaml
    from crashstudy.study.plan import load_study

    load_study(path)  # every problem of the file at once, with lines (its blocks: crashstudy.study.blocks)
    doc = load_yaml(path)
    data = dict(doc.data)
    if not data.get(block):
        raise InputError(
            [Problem(path, None, block, f"no {block}: block in this study (see docs/optimize.md)")]
        )
    base = Path(path).resolve().parent
    data["model"] = str((base / data["model"]).resolve())
    return data, base


def _finish(
    command: str, data: dict[str, Any], values: dict[str, float], out: Path, files: list[tuple[Path, Any]]
) -> None:
    """Run the optimum (or calibrated) values into ``out`` (its lock held by the caller), then write
    ``files`` beside them as one set (:func:`crashstudy.safefs.write_all`)."""
    from crashstudy.analysis.optimization import optimum_study
    from crashstudy.run.runner import run_plan
    from crashstudy.study.plan import load_study

    try:
        run_plan(load_study(optimum_study(data, values)), out, force=True, progress=False, locked=True)
        write_all(files)
    except KeyboardInterrupt:
        raise Stopped(
            f"{command} stopped while writing its results into {out}: they are incomplete; run {command} "
            "again with --force (it cannot resume)"
        ) from None


def _searching(command: str, out: Path) -> Stopped:
    return Stopped(
        f"{command} stopped during its search: nothing was written ({out} is as it was); {command} "
        "cannot resume: run it again"
    )


def _yaml(result: dict[str, Any]) -> str:
    import yaml

    return str(yaml.safe_dump(result, sort_keys=False))


def optimize_command(args: argparse.Namespace) -> int:
    from crashstudy.analysis.optimization import optimize
    from crashstudy.results.outdir import check_output
    from crashstudy.run.runner import output_folder

    data, _ = _study_dict(args.study, "optimize")
    out = Path(args.output or Path("results") / data["name"])
    with output_folder(out, args.study):  # held from the check to the last file written
        check_output(out, args.force, args.study, data["name"])
        try:
            result, history = optimize(data)
        except ValueError as exc:
            raise InputError([Problem(args.study, None, "optimize", str(exc))]) from None
        except KeyboardInterrupt:
            raise _searching("optimize", out) from None
        text = _yaml(result)
        _finish(
            "optimize",
            data,
            result["variables"],
            out,
            [
                (out / "history.csv", lambda fh: fh.write(history.to_csv(index=False).encode())),
                (out / "optimum.yaml", lambda fh: fh.write(text.encode())),
            ],
        )
    print(text.rstrip())
    print(f"wrote {out / 'optimum.yaml'}, {out / 'history.csv'} and the optimum's results in {out}")
    return EXIT_OK if result["feasible"] else 1


def calibrate_command(args: argparse.Namespace) -> int:
    from crashstudy.analysis.optimization import calibrate
    from crashstudy.results.outdir import check_output
    from crashstudy.run.runner import output_folder
    from crashstudy.schema.yamlio import load_yaml

    data, base = _study_dict(args.study, "calibrate")
    out = Path(args.output or Path("results") / data["name"])
    with output_folder(out, args.study):
        check_output(out, args.force, args.study, data["name"])
        try:
            result = calibrate(data, base, out)
        except (ValueError, FloatingPointError, FileNotFoundError) as exc:
            at: tuple[str, ...] = (
                ("calibrate", "data") if getattr(exc, "data_file", False) else ("calibrate",)
            )
            if len(at) == 2 and isinstance(data["calibrate"]["data"], dict):  # {path, channel, unit}
                at += (getattr(exc, "field", "path"),)
            line = load_yaml(args.study).line_of(at) if len(at) > 1 else None
            raise InputError([Problem(args.study, line, ".".join(at), str(exc))]) from None
        except KeyboardInterrupt:
            raise _searching("calibrate", out) from None
        t, y, model, units = result.pop("_fit")
        text = _yaml(result)
        fig = _fit_plot(t, y, model, data["calibrate"]["channel"], result, units)
        _finish(
            "calibrate",
            data,
            result["variables"],
            out,
            [
                (out / "calibrated.yaml", lambda fh: fh.write(text.encode())),
                (
                    out / "calibration.png",
                    lambda fh: fig.savefig(fh, format="png", dpi=100, bbox_inches="tight"),
                ),
            ],
        )
    print(text.rstrip())
    _uncertainty_warnings(result)
    print(f"wrote {out / 'calibrated.yaml'}, {out / 'calibration.png'} and the calibrated results in {out}")
    return EXIT_OK


def _uncertainty_warnings(result: dict[str, Any]) -> None:
    """A warning (stderr) for each calibrated variable the data do not determine."""
    from crashstudy.analysis.calibration_report import uncertainty_notes

    for line in uncertainty_notes(result.get("uncertainty") or {}):
        print(line, file=sys.stderr)


def _fit_plot(
    t: Any, y: Any, model: Any, channel: dict[str, Any], result: dict[str, Any], units: dict[str, str]
) -> Any:
    """The data-vs-fit figure (written by the caller with the other outputs)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    what = channel["quantity"] + (
        f" of spring {channel['spring']}"
        if channel.get("spring")
        else f" of node {channel['node']} ({channel.get('direction', 'x')})"
    )
    fig, ax = plt.subplots(figsize=(8, 4.5))
    ax.plot(t, y, ".", ms=3, color="0.4", label="data")
    ax.plot(t, model, "-", color="C3", lw=1.5, label="calibrated model")
    ax.set_xlabel(f"time [{units.get('time', '')}]")
    ax.set_ylabel(f"{channel['quantity'].replace('_', ' ')} [{units.get('value', '')}]")
    ax.set_title(
        f"{what}: rms error {result['rms_error']:.3g}, correlation {result['correlation']:.4f}", fontsize=10
    )
    ax.legend(loc="best")
    return fig
