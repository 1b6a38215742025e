"""Silent mistakes: valid input that cannot mean what its author meant (``validate`` and ``run`` refuse it).

The schema checks each field and the study stage each axis value; what neither can see is checked
here on a whole :class:`~crashstudy.study.plan.Plan`: an axis whose values all give the same model (it
changes nothing: ``impact_velocity`` on a model at rest), a fixed ``time_step.dt`` above the critical
step of some variants (each would fail at run time), and numbers that contradict the model's
``units`` (warnings only, :mod:`crashstudy.schema.plausible`). The Python API does not call this:
``run_study`` still runs such a study and marks the refused variants as failed.
"""

from __future__ import annotations

import math

import numpy as np

from crashstudy.arrays.batch import build_batch, fixed_dt_check
from crashstudy.arrays.compiler import apply_axis
from crashstudy.errors import Problem
from crashstudy.metrics.record import plan_warnings
from crashstudy.schema import validate_model_data
from crashstudy.schema.study import Study
from crashstudy.schema.yamlio import LoadedYaml, loads_yaml
from crashstudy.study.plan import DICT_STUDY, Axis, Plan, _apply_set
from crashstudy.study.work import step_dims

MAX_DT_CHECK = 4_000_000  #: variants whose critical step is checked against a fixed dt (the first ones)


def check_plan(plan: Plan) -> tuple[list[Problem], list[str]]:
    """Problems (exit 2) and warnings of a valid plan that the schema cannot see.

    Problems: a study axis whose values all give the same model (it changes nothing), and a fixed
    ``time_step.dt`` above the critical step of every variant (no variant could run).
    Warnings: a fixed ``dt`` above the critical step of some variants (those fail at run time with the
    reason, the others run), and numbers that contradict the model's ``units``
    (:mod:`crashstudy.schema.plausible`)."""
    from crashstudy.arrays.vibration import first_period
    from crashstudy.schema.plausible import unit_warnings

    sdoc = loads_yaml(plan.study_text, file=plan.study_file) if plan.study_text else None
    mdoc = loads_yaml(plan.model_text, file=plan.model_file)
    problems = [_axis_problem(plan, sdoc, ax) for ax in plan.axes if not _axis_changes_model(plan, ax)]
    refused, dt_crit = _dt_refused(plan)
    dt_warnings = []
    # no variant can run at the dt: that is the one message on it (not also the interval warning)
    dt_refused_all = refused.size == min(plan.n_variants, MAX_DT_CHECK)
    if dt_refused_all:
        problems.append(_dt_problem(plan, sdoc, mdoc, refused, dt_crit))
    elif refused.size:  # the others can run: these fail with the reason (failure isolation)
        p = _dt_problem(plan, sdoc, mdoc, refused, dt_crit)
        dt_warnings.append(f"{p.file}:{p.line}: {p.field}: {p.message}; those variants will fail")
    data = mdoc.data if sdoc is None else _apply_set(mdoc.data, Study.model_validate(sdoc.data).set, sdoc)
    m, _ = validate_model_data(data)
    where = plan.study_file or plan.model_file
    period = first_period(plan.topology, plan.params(0, 1)[:, 0])
    warnings = dt_warnings + ([] if dt_refused_all else _dt_interval_warnings(plan, sdoc, mdoc))
    warnings += unit_warnings(m, _first_dt_crit(plan), where, period) if m is not None else []
    warnings += _speed_axis_warnings(plan, where)
    warnings += _repeat_warnings(plan, sdoc)
    warnings += plan_warnings(plan)
    if plan.study_file == DICT_STUDY:
        problems = [
            Problem(p.file, None, p.field, p.message) if p.file == DICT_STUDY else p for p in problems
        ]
    return problems, warnings


def _repeat_warnings(plan: Plan, sdoc: LoadedYaml | None) -> list[str]:
    """A matrix axis alone in its dimension that lists a value more than once: the variants of the
    repeats are copies of others (same model, same results), computed and stored again."""
    out: list[str] = []
    for ax in plan.axes:
        if sum(o.dim == ax.dim for o in plan.axes) > 1:
            continue  # a zip group: a value repeated there may pair with different values of the others
        vals, counts = np.unique(ax.values, return_counts=True)
        if counts.max(initial=1) > 1:
            twice = ", ".join(f"{v:g} ({c} times)" for v, c in zip(vals, counts, strict=True) if c > 1)
            copies = plan.n_variants // len(ax.values) * int((counts - 1).sum())
            out.append(
                _at_axis(
                    plan,
                    sdoc,
                    ax.path,
                    f"lists {twice}: {copies} of the {plan.n_variants} variants "
                    "repeat others (same model, same results)",
                ).format()
            )
    return out


def _speed_axis_warnings(plan: Plan, where: str) -> list[str]:
    """The slowest ``impact_velocity`` axis value > 0, when it is slower than a walking pace."""
    from crashstudy.schema.plausible import speed_warnings

    out: list[str] = []
    for ax in plan.axes:
        if ax.ref.op == "speed" and np.any(ax.values > 0):
            slowest = float(np.min(ax.values[ax.values > 0]))
            out += speed_warnings(plan.topology.units, [slowest], f"{ax.path} value", where)
    return out


NOOP_COLUMNS = 200_000  #: parameter columns at most built to check an axis for doing nothing
NOOP_VALUES = 1024  #: distinct values of the axis tried at most (always its smallest and largest)
NOOP_SAMPLES = 64  #: random settings of the other axes tried when all of them would exceed NOOP_COLUMNS


def _axis_changes_model(plan: Plan, ax: Axis) -> bool:
    """Whether the values of ``ax`` give different parameters for some setting of the other axes that
    occurs in the study (an axis may matter only for some values of another: an initial velocity
    scaled by an ``impact_velocity`` of 0 or 1). The settings that occur are the product over the
    study's dimensions (matrix axes, zip groups, the design) of each dimension's rows of the other
    axes: every one is tried while that stays under NOOP_COLUMNS parameter columns, else the first,
    the last and NOOP_SAMPLES random ones; of the axis itself at most NOOP_VALUES distinct values
    (with its smallest and largest). The cost follows the distinct values, never the variant count
    (np.unique over the 10^6 variants' settings took 2.3 s). The axes are applied in the study's
    order, as for the variants themselves."""
    rng = np.random.default_rng(0)
    vals = np.unique(ax.values)
    if len(vals) < 2:
        return True  # one value: a fixed setting, like `set`
    if len(vals) > NOOP_VALUES:
        vals = vals[np.unique(np.concatenate([[0, len(vals) - 1], rng.choice(len(vals), NOOP_VALUES - 2)]))]
    others = [o for o in plan.axes if o is not ax]
    dims = sorted({o.dim for o in others})
    rows = {d: np.stack([o.values for o in others if o.dim == d], axis=1) for d in dims}  # (shape[d], axes)
    total = math.prod(len(r) for r in rows.values())
    k = len(vals)
    if total * k <= NOOP_COLUMNS:
        rows = {d: np.unique(r, axis=0) for d, r in rows.items()}
        sizes = [len(rows[d]) for d in dims]
        pick = np.unravel_index(np.arange(math.prod(sizes)), sizes) if dims else ()
    else:
        n = min(NOOP_SAMPLES, max(1, NOOP_COLUMNS // k - 2))
        pick = tuple(np.concatenate([[0, len(rows[d]) - 1], rng.integers(0, len(rows[d]), n)]) for d in dims)
    at = dict(zip(dims, pick, strict=True))
    S = len(pick[0]) if dims else 1
    P = np.repeat(plan.base[:, None], S * k, axis=1)
    col = {d: 0 for d in dims}
    for other in plan.axes:
        if other is ax:
            apply_axis(P, other.ref, np.tile(vals, S))
        else:
            apply_axis(P, other.ref, np.repeat(rows[other.dim][at[other.dim], col[other.dim]], k))
            col[other.dim] += 1
    P = P.reshape(P.shape[0], S, k)
    return bool(np.any((P != P[:, :, :1])[~_inert_rows(plan)]))


def _inert_rows(plan: Plan) -> np.ndarray:
    """Parameter rows no equation reads: the mass of a node fixed in every direction (it never moves, and
    the critical step counts it as infinite, arrays.timestep). An axis setting only these changes nothing."""
    inert = np.zeros(plan.base.shape[0], dtype=bool)
    inert[plan.topology.blocks["mass"]] = plan.topology.fixed.all(axis=1)
    return inert


def _axis_loc(sdoc: LoadedYaml | None, path: str) -> tuple[str | int, ...]:
    if sdoc is not None and isinstance(sdoc.data.get("zip"), list):
        for g, grp in enumerate(sdoc.data["zip"]):
            if isinstance(grp, dict) and path in grp:
                return ("zip", g, path)
    return ("matrix", path)


def _axis_problem(plan: Plan, sdoc: LoadedYaml | None, ax: Axis) -> Problem:
    n = len(np.unique(ax.values))
    if ax.ref.op == "speed":
        why = (
            "the model gives no node an initial_velocity, and impact_velocity rescales each node's initial "
            "velocity to this speed keeping its direction; give the moving nodes an initial_velocity"
        )
    elif ax.ref.slots and all(_inert_rows(plan)[list(ax.ref.slots)]):
        why = "it sets the mass of a node fixed in every direction, which never moves"
    elif ax.ref.op == "scale":
        why = "it scales values that are all zero"
    else:
        why = "the field it sets does not reach the model"
    return _at_axis(
        plan,
        sdoc,
        ax.path,
        f"axis {ax.path!r} changes nothing: its {n} values all give the same model ({why})",
    )


def _at_axis(plan: Plan, sdoc: LoadedYaml | None, path: str, message: str) -> Problem:
    """``message`` placed at axis ``path``: its line in the study file and its field (matrix or zip)."""
    loc = _axis_loc(sdoc, path)
    file, line = (sdoc.file, sdoc.line_of(loc)) if sdoc is not None else (plan.study_file, None)
    return Problem(file, line, ".".join(str(p) for p in loc), message)


def _first_dt_crit(plan: Plan) -> float:
    _, steps = build_batch(plan.topology, plan.params(0, 1), plan.interval)
    return float(steps.dt_crit[0])


def _dt_refused(plan: Plan) -> tuple[np.ndarray, np.ndarray]:
    """Variants (indices, among the first ``MAX_DT_CHECK``) whose fixed dt is above their critical step,
    and the critical step of each.

    The step depends on no initial velocity, so the critical steps are computed once per distinct
    setting of the dimensions (matrix axes, zip groups, design rows) that hold an axis changing
    anything else: a matrix over masses x curve scales x impact speeds computes masses x scales steps,
    and only the critical step (``fixed_dt_check``), not whole batches. Variants are listed only when some
    are refused."""
    if plan.topology.time_step_mode != "dt":
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    shape, dims = _step_dims(plan)
    n_steps = math.prod(shape[d] for d in dims)
    if not plan.shape or n_steps > MAX_DT_CHECK:  # a study whose every dimension matters: its first variants
        return _refused_of(plan, np.arange(min(plan.n_variants, MAX_DT_CHECK)))
    sub = tuple(shape[d] for d in dims)
    refused = np.zeros(n_steps, dtype=bool)
    crit = np.zeros(n_steps)
    for lo in range(0, n_steps, 65536):
        hi = min(n_steps, lo + 65536)
        full = np.zeros((len(shape), hi - lo), dtype=np.int64)  # the other dimensions at their first value
        if dims:  # none: only initial velocities vary, one critical step for every variant
            full[list(dims)] = np.unravel_index(np.arange(lo, hi), sub)
        at_lo = np.asarray(np.ravel_multi_index(tuple(full), shape))
        refused[lo:hi], crit[lo:hi] = fixed_dt_check(plan.topology, plan.params_at(at_lo))
    if not refused.any():
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    idx = np.arange(min(plan.n_variants, MAX_DT_CHECK))
    at = (
        np.ravel_multi_index(tuple(np.unravel_index(idx, shape)[d] for d in dims), sub)
        if dims
        else np.zeros_like(idx)
    )
    bad = np.flatnonzero(refused[at])
    return idx[bad], crit[at[bad]]


def _step_dims(plan: Plan) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """(the plan's shape, the dimensions holding an axis that sets anything but initial velocities)."""
    return tuple(plan.shape), step_dims(plan)


def _refused_of(plan: Plan, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Refused variants among ``idx`` (ascending) and their critical steps, a chunk at a time."""
    out: list[np.ndarray] = [np.zeros(0, dtype=np.int64)]
    crit: list[np.ndarray] = [np.zeros(0)]
    for lo in range(0, len(idx), 65536):
        part = idx[lo : lo + 65536]
        refused, dt_crit = fixed_dt_check(plan.topology, plan.params_at(part))
        out.append(part[refused])
        crit.append(dt_crit[refused])
    return np.concatenate(out), np.concatenate(crit)


def _dt_interval_warnings(plan: Plan, sdoc: LoadedYaml | None, mdoc: LoadedYaml) -> list[str]:
    """A fixed ``dt`` above the history interval: the step is lowered to the interval (it divides the
    interval exactly, docs/format.md), so the run takes dt / interval times the steps asked for."""
    if plan.topology.time_step_mode != "dt":
        return []
    given = [ax.values for ax in plan.axes if ax.path == "time_step.dt"]  # else every variant has the base's
    dt = float(np.max(given[0])) if given else float(plan.base[plan.topology.blocks["time_step"].start])
    if dt <= plan.interval * (1.0 + 1e-9):
        return []
    file, line = _dt_where(plan, sdoc, mdoc)
    return [
        f"{file}:{line}: time_step.dt: dt={dt:.6g} is above output.interval={plan.interval:.6g}, so the step "
        f"is lowered to {plan.interval:.6g} ({dt / plan.interval:.3g} x the steps asked for); to run at dt, "
        f"set output.interval to a multiple of it (e.g. {dt:.6g})"
    ]


def _dt_where(plan: Plan, sdoc: LoadedYaml | None, mdoc: LoadedYaml) -> tuple[str, int | None]:
    """(file, line) of the fixed ``time_step.dt``: the study's ``set`` or axis when it gives it, else the model's."""
    if sdoc is not None:
        keys = [key for key in (sdoc.data.get("set") or {}) if key in ("time_step", "time_step.dt")]
        loc: tuple[str | int, ...] = ("set", keys[0]) if keys else _axis_loc(sdoc, "time_step.dt")
        if keys or any(ax.path == "time_step.dt" for ax in plan.axes):
            return sdoc.file, sdoc.line_of(loc)
    return mdoc.file, mdoc.line_of(("time_step", "dt"))


def _dt_problem(
    plan: Plan, sdoc: LoadedYaml | None, mdoc: LoadedYaml, refused: np.ndarray, dt_crit: np.ndarray
) -> Problem:
    worst = int(np.argmin(dt_crit))
    k = int(refused[worst])
    dt = float(plan.params(k, k + 1)[plan.topology.blocks["time_step"].start, 0])
    values = plan.axis_values(0, plan.n_variants) if plan.n_variants <= MAX_DT_CHECK else {}
    at = ", ".join(f"{p}={float(v[k]):g}" for p, v in values.items())
    where = []
    for path, v in values.items():  # axis values that only refused variants have
        bad = set(np.unique(v[refused]).tolist())
        if bad != set(np.unique(v).tolist()):
            where.append(f"{path} in [{', '.join(f'{x:g}' for x in sorted(bad))}]")
    msg = (
        f"dt={dt:.6g} is above the critical step of {len(refused)} of {plan.n_variants} variant(s): "
        f"dt_crit={float(dt_crit[worst]):.6g} at variant {k}"
        + (f" ({at})" if at else "")
        + (f"; refused where {' and '.join(where)}" if where else "")
        + f"; use a dt below {float(dt_crit[worst]):.6g} or time_step: {{safety_factor: 0.9}}"
    )
    file, line = _dt_where(plan, sdoc, mdoc)
    return Problem(file, line, "time_step.dt", msg)
