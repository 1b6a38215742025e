"""Expansion stage: a study file (or a lone model) -> a :class:`Plan` of numbered variants.

A plan holds the compiled topology, the base parameter vector and the study axes; it produces the
parameter matrix of any range of variants on demand (:meth:`Plan.params`), so a study of 10^6
variants is never materialised. Variants are numbered in row-major order of the axes as written:
matrix axes first, then one axis per zip group.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from crashstudy.arrays.compiler import Topology, apply_axis, compile_model
from crashstudy.arrays.parameter_checks import check_parameters
from crashstudy.errors import InputError, Problem
from crashstudy.kernel.output import HISTORY_SHAPES
from crashstudy.schema import LoadedModel, file_kind, parse_model, refuse_foreign, validate_model_data
from crashstudy.schema.yamlio import LoadedYaml, load_yaml, loads_yaml, not_regular
from crashstudy.study.axes import Axis, _axes
from crashstudy.study.overrides import _apply_set, _set_problem
from crashstudy.study.values import study_problem
from crashstudy.study.work import WORK_ENV, WORK_RATE, estimate_work, format_duration, max_work

if TYPE_CHECKING:  # pydantic is imported by the functions that validate: a Plan unpickled by a --jobs
    from crashstudy.schema.model import Model  # worker needs none of it

DEFAULT_SAMPLES = 1000
MAX_VARIANTS = 100_000_000  # one results.nc; its axis coordinates alone take 0.8 GB each
MAX_SAMPLE_BYTES = (
    256 * 2**20
)  # history samples of one variant (histories and the kernel's 4 energy records):
# the runner's HISTORY_BUDGET of a chunk, so that one variant always fits a chunk


@dataclass(frozen=True)
class Plan:
    """Everything needed to run a study; picklable, free of pydantic objects."""

    name: str
    topology: Topology
    base: np.ndarray  # (n_params,)
    axes: tuple[Axis, ...]
    shape: tuple[int, ...]  # size of each matrix axis / zip group
    interval: float  # history sampling interval [time]
    n_out: int  # number of history samples
    model_text: str
    study_text: str
    model_file: str
    study_file: str
    regression: dict[str, dict[str, float]]
    work: float = 0.0  # estimated element-steps of the whole run (springs x time steps, summed over variants)

    @property
    def n_variants(self) -> int:
        return math.prod(self.shape) if self.shape else 1

    @property
    def times(self) -> np.ndarray:
        return np.arange(self.n_out) * self.interval

    @functools.cached_property
    def variants_distinct(self) -> bool:
        """Whether no two variants have the same axis values: along every dimension (a matrix axis or a
        zip group) the rows of values are distinct, so their combinations are too."""
        for dim in range(len(self.shape)):
            rows = np.stack([ax.values for ax in self.axes if ax.dim == dim], axis=1)
            if len(np.unique(rows, axis=0)) < len(rows):
                return False
        return True

    @functools.cached_property
    def varying_curves(self) -> frozenset[int]:
        """The curves some axis changes: index ``c`` when an axis sets one of its knots (the axes' parameter
        slots that fall in a curve's knots), ``-1 - c`` when axes only scale it (``scale``, ``x_scale``:
        one factor per variant on a constant shape). The generated kernel keeps the other curves as
        constants, and a scaled curve's shape as constants too (kernel.gen_shape)."""
        touched = {s for ax in self.axes for s in ax.ref.slots}
        off, blocks = self.topology.curve_offsets, self.topology.blocks
        points = {
            c
            for c in range(len(off) - 1)
            for b in ("cx", "cy_")
            if b in blocks
            and any(blocks[b].start + k in touched for k in range(int(off[c]), int(off[c + 1])))
        }
        fac = blocks.get("cfac", slice(0, 0))
        scaled = {(s - fac.start) // 2 for s in touched if fac.start <= s < fac.stop} - points
        return frozenset(points | {-1 - c for c in scaled})

    def axis_values(self, lo: int, hi: int) -> dict[str, np.ndarray]:
        """Value of every axis for variants ``lo`` .. ``hi - 1``."""
        return self.axis_values_at(np.arange(lo, hi))

    def axis_values_at(self, idx: np.ndarray) -> dict[str, np.ndarray]:
        """Value of every axis for the variants numbered ``idx``."""
        if not self.shape:
            return {}
        multi = np.unravel_index(idx, self.shape)
        return {ax.path: ax.values[multi[ax.dim]] for ax in self.axes}

    def params(self, lo: int, hi: int) -> np.ndarray:
        """Parameter matrix (n_params, hi - lo) of variants ``lo`` .. ``hi - 1``."""
        return self.params_at(np.arange(lo, hi))

    def params_at(self, idx: np.ndarray) -> np.ndarray:
        """Parameter matrix (n_params, len(idx)) of the variants numbered ``idx``."""
        P = np.repeat(self.base[:, None], len(idx), axis=1)
        for ax, vals in zip(self.axes, self.axis_values_at(idx).values(), strict=True):
            apply_axis(P, ax.ref, np.asarray(vals, dtype=np.float64))
        return P


def _interval(m: Model, end: float) -> float:
    """History sampling interval: the model's, or about DEFAULT_SAMPLES samples up to ``end``."""
    return m.output.interval or end / DEFAULT_SAMPLES


def plan_from_model(lm: LoadedModel) -> Plan:
    """A one-variant plan for ``crashstudy simulate``."""
    return _plan(lm.model, lm.doc, None, [], [], None, {})


def _plan(
    m: Model,
    mdoc: LoadedYaml,
    sdoc: LoadedYaml | None,
    axes: list[Axis],
    shape: list[int],
    name: str | None,
    regression: dict[str, dict[str, float]],
    compiled: tuple[Topology, np.ndarray] | None = None,
) -> Plan:
    topo, base = compiled or compile_model(m)
    end = max([m.end_time] + [float(v) for ax in axes if ax.path == "end_time" for v in ax.values])
    interval = _interval(m, end)
    n_out = int(math.floor(end / interval + 1e-9)) + 1
    per = {"node": topo.n_nodes * topo.dim, "spring": topo.n_springs, "wall": len(topo.wall_ids)}
    width = sum(per[HISTORY_SHAPES[h][0]] if HISTORY_SHAPES[h] else 1 for h in topo.histories) + 4
    if n_out * 8 * width > MAX_SAMPLE_BYTES:
        keys = [k for k in (sdoc.data.get("set") or {} if sdoc else {}) if k.split(".")[0] == "output"]
        doc, at = (sdoc, ("set", keys[0])) if sdoc and keys else (mdoc, ("output", "interval"))
        raise InputError(
            [
                study_problem(
                    doc,
                    at,
                    f"{n_out:.3g} history samples (end_time {end:g} / output.interval "
                    f"{interval:g}) of {width} values take {n_out * 8 * width / 2**20:.3g} MiB per "
                    f"variant, at most {MAX_SAMPLE_BYTES / 2**20:g} MiB: use a longer interval",
                )
            ]
        )
    if sdoc is None:  # a lone model: what only its numbers can break (a step count that overflows)
        check = check_parameters(topo, base[:, None], interval)
        if check.bad[0]:
            raise InputError([study_problem(mdoc, ("end_time",), check.reason(0))])
    plan = Plan(
        name=name or m.name,
        topology=topo,
        base=base,
        axes=tuple(axes),
        shape=tuple(shape),
        interval=interval,
        n_out=n_out,
        model_text=mdoc.text,
        study_text=sdoc.text if sdoc else "",
        model_file=mdoc.file,
        study_file=sdoc.file if sdoc else "",
        regression=regression,
    )
    work, worst, steps = estimate_work(plan)
    limit = max_work()
    if work > limit:
        on_axis = any(a.path == "end_time" for a in axes)
        doc, loc = (sdoc, _axis_where(sdoc, "end_time")) if sdoc and on_axis else (mdoc, ("end_time",))
        P = plan.params(worst, worst + 1)[:, 0]
        b = topo.blocks
        raise InputError(
            [
                study_problem(
                    doc,
                    loc,
                    (
                        f"the run would take about {work:.3g} element-steps (springs x time steps, summed over the "
                        f"{plan.n_variants:,} variant{'s' if plan.n_variants != 1 else ''}), about "
                        f"{format_duration(work / WORK_RATE)} at {WORK_RATE:.0e} a second; the longest variant ({worst}) takes "
                        f"{steps:.3g} steps to end_time {P[b['end_time'].start]:g}; at most {limit:.3g}: shorten end_time, "
                        f"use a larger time step, or set the environment variable {WORK_ENV} (e.g. {WORK_ENV}={work * 1.1:.2g})"
                    ),
                )
            ]
        )
    return dataclasses.replace(plan, work=work)


def _axis_where(sdoc: LoadedYaml, path: str) -> tuple[str | int, ...]:
    """Where the study file gives axis ``path``: ``matrix.PATH`` or ``zip.G.PATH``."""
    for g, grp in enumerate(sdoc.data.get("zip") or []):
        if isinstance(grp, dict) and path in grp:
            return ("zip", g, path)
    return ("matrix", path)


def _model_path(sdoc: LoadedYaml, base_dir: Path, name: str) -> Path:
    """The study's model file, or an :class:`InputError` at its ``model:`` line saying why it cannot be used."""
    if "\0" in name:
        raise InputError(
            [
                study_problem(
                    sdoc,
                    ("model",),
                    "the model path contains a NUL character (\\0); expected the path of a YAML file",
                )
            ]
        )
    try:
        path = (base_dir / name).resolve() if not os.path.isabs(name) else Path(name)
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise InputError(
            [study_problem(sdoc, ("model",), f"model file not found: {base_dir / name}")]
        ) from None
    except (OSError, RuntimeError, ValueError) as exc:  # a symbolic-link loop, a path too long, ...
        why = (
            "a loop of symbolic links"
            if "loop" in str(exc).lower() or getattr(exc, "errno", 0) == 40
            else (getattr(exc, "strerror", None) or str(exc))
        )
        raise InputError(
            [
                study_problem(
                    sdoc,
                    ("model",),
                    f"cannot use the model path {base_dir / name}: {why} "
                    "(symbolic links are followed to a file)",
                )
            ]
        ) from None
    why = not_regular(mode)  # a directory, or a FIFO or device (reading one would wait or never end)
    if why:
        raise InputError([study_problem(sdoc, ("model",), f"model path {path}: {why}")])
    return path


DICT_STUDY = "study (dict)"  #: how a study given from Python as a dict is named in messages (it has no lines)


def load_study(source: str | os.PathLike[str] | dict[str, Any]) -> Plan:
    """Read and validate a study (a path, or a dict as the YAML would load) into a :class:`Plan`."""
    if not isinstance(source, dict):
        return _load_study(source)
    try:
        return _load_study(source)
    except (
        InputError
    ) as exc:  # a dict has no file and no lines: "study (dict): matrix.x: ...", never "<...>:4:"
        raise InputError(
            [p if p.file != DICT_STUDY else Problem(p.file, None, p.field, p.message) for p in exc.problems]
        ) from None


def _not_a_study(sdoc: LoadedYaml) -> Problem:
    from crashstudy.schema.model import Model

    keys = ", ".join(k for k in sdoc.data if k in Model.model_fields)
    name = sdoc.file if sdoc.file != DICT_STUDY else "MODEL.yaml"
    return Problem(
        sdoc.file,
        None,
        "",
        f"this is a model, not a study (it has {keys}): run one model with "
        f"`crashstudy simulate {name}`, or write a study file with `model: {name}` and the axes to "
        "vary under `matrix:`",
    )


def _load_study(source: str | os.PathLike[str] | dict[str, Any]) -> Plan:
    from pydantic import ValidationError

    from crashstudy.schema.model import Model
    from crashstudy.schema.report import located, pydantic_problems
    from crashstudy.schema.study import Study

    if isinstance(source, dict):
        import yaml

        sdoc = loads_yaml(yaml.safe_dump(source, sort_keys=False), file=DICT_STUDY)
        base_dir = Path.cwd()
    else:
        sdoc = load_yaml(source)
        base_dir = Path(source).resolve().parent
    refuse_foreign(sdoc)
    if file_kind(sdoc.data) == "model":
        raise InputError([_not_a_study(sdoc)])
    try:
        study = Study.model_validate(sdoc.data)
    except ValidationError as exc:
        raise InputError(pydantic_problems(exc, sdoc, Study)) from None
    model_path = _model_path(sdoc, base_dir, study.model)
    mdoc = load_yaml(str(model_path))
    parse_model(mdoc)  # the model alone must be valid: its own errors point into its own file
    data = _apply_set(mdoc.data, study.set, sdoc)
    m, found = validate_model_data(data)
    if isinstance(found, ValidationError) or found:
        errs = (
            pydantic_problems(found, LoadedYaml(data, mdoc.text, mdoc.file, {}), Model)
            if isinstance(found, ValidationError)
            else located(LoadedYaml(data, "", mdoc.file, {}), found)
        )
        raise InputError([_set_problem(sdoc, study.set, p) for p in errs])
    assert m is not None
    topo, base = compile_model(m)
    ends = [
        v
        for grp in [study.matrix, *study.zip]
        for path, vals in grp.items()
        if path == "end_time"
        for v in vals
    ]
    interval = _interval(m, max([m.end_time, *ends]))
    axes, shape, problems = _axes(study, sdoc, topo, data, base, interval)
    from crashstudy.study.blocks import Context, check_blocks

    problems += check_blocks(Context(study, sdoc, base_dir, topo, data, base, interval))
    if problems:
        raise InputError(problems)

    if math.prod(shape) > MAX_VARIANTS:
        raise InputError(
            [
                study_problem(
                    sdoc,
                    ("matrix",),
                    f"{math.prod(shape):,} variants: at most "
                    f"{MAX_VARIANTS:,} fit in one result file; split the study",
                )
            ]
        )
    regression = {k: v.model_dump() for k, v in study.regression.items()}
    plan = _plan(m, mdoc, sdoc, axes, shape, study.name, regression, (topo, base))
    check = check_parameters(topo, base[:, None], plan.interval)
    if not axes and check.bad[0]:  # with axes, each of their values was checked with the rest of the model
        raise InputError(
            [study_problem(sdoc, ("model",), f"the model (after 'set') is invalid: {check.reason(0)}")]
        )
    return plan
