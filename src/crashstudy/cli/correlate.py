"""``crashstudy correlate DIR --test TEST ...``: the ISO/TS 18571 rating of every variant's history against a
test curve (docs/correlation.md): ``correlation.csv`` in the result folder, the best variants printed."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

QUANTITIES = {
    "acceleration": "acceleration",
    "velocity": "velocity",
    "displacement": "displacement",
    "force": "spring_force",
    "elongation": "spring_elongation",
    "spring_force": "spring_force",
    "spring_elongation": "spring_elongation",
}
CSV_NAME = "correlation.csv"
SHOWN = 10  # best variants printed


def register(sub: Any) -> dict[str, Callable[[argparse.Namespace], int]]:
    co = sub.add_parser(
        "correlate",
        help="ISO/TS 18571 rating of every variant's history against a test curve (correlation.csv)",
    )
    co.add_argument("dir", help="result folder (run or simulate, with histories kept)")
    co.add_argument(
        "--test",
        required=True,
        help="the test curve: a CSV with a time column (model units unless "
        "--unit), or an ISO-MME test (.mme, its folder or a .zip; converted from its channel's unit)",
    )
    co.add_argument(
        "--channel",
        help="ISO-MME: the 16-character channel code ('?' any one character); CSV: the value "
        "column (default value)",
    )
    co.add_argument(
        "--unit",
        help="the unit of the test values when the file does not say it or says it wrong "
        "(g, m/(s*s), km/h, mm, kN, ...)",
    )
    co.add_argument(
        "--item",
        required=True,
        help="node id (acceleration, velocity, displacement) or spring id (force, elongation)",
    )
    co.add_argument("--quantity", required=True, choices=sorted(QUANTITIES), help="the history rated")
    co.add_argument(
        "--direction",
        choices=["x", "y", "r"],
        default="x",
        help="node quantities: the component x or y, or r the magnitude (default x)",
    )
    co.add_argument(
        "--window",
        nargs=2,
        type=float,
        metavar=("T0", "T1"),
        help="rate only within T0 .. T1 [model time units] (default: where both curves are defined)",
    )
    co.add_argument(
        "--cfc",
        type=int,
        help="filter both curves with this SAE J211 channel frequency class first (e.g. 60, 180, 600, 1000)",
    )
    return {"correlate": correlate_command}


def _fail(where: str, field: str, message: str, line: int | None = None) -> Exception:
    from crashstudy.errors import InputError, Problem

    return InputError([Problem(where, line, field, message)])


def model_curves(ds: Any, quantity: str, item: str, direction: str, where: str) -> Any:
    """(variant, time) values of ``quantity`` of ``item`` (a node's component or magnitude, or a spring's)."""
    import numpy as np

    from crashstudy.analysis.plot import _need_histories

    name = QUANTITIES[quantity]
    _need_histories(ds, [name])
    dim = "spring" if name.startswith("spring_") else "node"
    valid = [str(v) for v in ds[dim].values]
    if item not in valid:
        raise _fail(where, "--item", f"{quantity} needs a {dim} id; {item!r} is none of {', '.join(valid)}")
    da = ds[name].sel({dim: item})
    if dim == "spring":
        return np.asarray(da.transpose("variant", "time").values, dtype=float)
    axes = [str(a) for a in ds["axis"].values] if "axis" in ds.coords else ["x"]
    v = np.asarray(da.transpose("variant", "time", ...).values, dtype=float).reshape(
        ds.sizes["variant"], ds.sizes["time"], -1
    )
    if direction == "r":
        return np.sqrt((v**2).sum(axis=-1))
    if direction not in axes:
        raise _fail(
            where, "--direction", f"the model moves along {', '.join(axes)} only; use one of them or r"
        )
    return v[:, :, axes.index(direction)]


def _filtered(t: Any, y: Any, cfc: int, second: float, what: str, where: str) -> Any:
    import numpy as np

    from crashstudy.metrics.criteria_filter import j211_filter, rate_too_low

    dt = np.diff(t)
    if np.ptp(dt) > 1e-6 * np.mean(dt):
        raise _fail(where, "--cfc", f"{what} is not sampled at a constant step; the CFC filter needs one")
    if rate_too_low(np.array([float(np.mean(dt))]) / second, cfc)[0]:
        raise _fail(where, "--cfc", f"{what} is sampled too coarsely (step {np.mean(dt):g}) for CFC {cfc:g}")
    y2 = np.atleast_2d(y)
    return j211_filter(
        y2, np.full(len(y2), y2.shape[1]), np.full(len(y2), float(np.mean(dt))), cfc, second=second
    )


def correlate_command(args: argparse.Namespace) -> int:
    import numpy as np
    import pandas as pd

    from crashstudy.analysis.iso18571 import grade, rate_histories
    from crashstudy.analysis.optimization import DataFileError, read_data
    from crashstudy.analysis.plot import study_axes
    from crashstudy.errors import InputError, Problem
    from crashstudy.results.reader import open_results
    from crashstudy.safefs import write_text

    where = str(args.dir)
    if args.window is not None and not args.window[1] > args.window[0]:
        raise _fail(where, "--window", f"expected T0 < T1; got {args.window[0]:g} {args.window[1]:g}")
    if args.cfc is not None and not args.cfc > 0:
        raise _fail(where, "--cfc", f"expected a positive channel frequency class; got {args.cfc:g}")
    try:
        res = open_results(args.dir)
    except FileNotFoundError as exc:
        raise _fail(where, "", str(exc)) from None
    try:
        ds = res.dataset
        try:
            t_test, y_test = read_data(
                Path(args.test),
                channel=args.channel,
                unit=args.unit,
                quantity=args.quantity,
                system=str(ds.attrs.get("units", "SI")),
            )
        except FileNotFoundError:
            raise _fail(
                args.test,
                "--test",
                "no such file: expected a CSV with a time column and the column "
                f"{args.channel or 'value'!r}, or an ISO-MME test",
            ) from None
        except (DataFileError, OSError) as exc:
            raise _fail(args.test, "--test", str(exc)) from None
        models = model_curves(ds, args.quantity, args.item, args.direction, where)
        t_model = np.asarray(ds["time"].values, dtype=float)
        second = 1000.0 if str(ds["time"].attrs.get("units", "s")) == "ms" else 1.0
        if args.cfc is not None:
            models = _filtered(t_model, models, args.cfc, second, f"the histories of {where}", where)
            y_test = _filtered(t_test, y_test, args.cfc, second, f"the test curve {args.test}", args.test)[0]
        ok = np.asarray(ds["status"].values).astype(str) == "ok"
        if not ok.all():
            models = np.where(ok[:, None], models, np.nan)
        try:
            scores = rate_histories(
                t_model, models, t_test, y_test, second, tuple(args.window) if args.window else None
            )
        except ValueError as exc:
            raise _fail(args.test, "--window" if args.window else "--test", str(exc)) from None
        axes = study_axes(ds)
        table = pd.DataFrame({"variant": np.asarray(ds["variant"].values)})
        for a in axes:
            table[a] = np.asarray(ds[a].values)
        for k in ("R", "Z", "EP", "EM", "ES"):
            table[k] = scores[k]
        table["grade"] = [grade(float(r)) for r in scores["R"]]
        units = str(ds["time"].attrs.get("units", ""))
    except InputError as exc:  # name the folder as the user typed it
        raise InputError(
            [
                Problem(p.file if p.file != str(res.dir) else where, p.line, p.field, p.message)
                for p in exc.problems
            ]
        ) from None
    finally:
        res.close()
    out = Path(args.dir) / CSV_NAME
    write_text(out, table.to_csv(index=False))
    best = table.sort_values("R", ascending=False, na_position="last").head(SHOWN)
    print(
        f"ISO/TS 18571 rating of {args.quantity} of {args.item}"
        f"{f' ({args.direction})' if QUANTITIES[args.quantity] in ('acceleration', 'velocity', 'displacement') else ''}"
        f" against {args.test} on {float(scores['t0']):g} .. {float(scores['t1']):g} {units} "
        f"({int(scores['samples'])} samples at 10 kHz{f', CFC {args.cfc:g}' if args.cfc else ''}); "
        f"best {len(best)} of {len(table)}:"
    )
    with pd.option_context(
        "display.width", 160, "display.max_columns", 30, "display.float_format", "{:.4f}".format
    ):
        print(best.to_string(index=False))
    failed = int((~ok).sum())
    if failed:
        print(f"{failed} failed variant(s) have no rating (empty grade)")
    print(f"wrote {out}")
    return 0
