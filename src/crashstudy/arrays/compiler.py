"""Compile step: a validated :class:`Model` -> plain arrays (the last pydantic-aware stage).

A model compiles into a :class:`Topology` (what every variant of a study shares: ids, connectivity,
material types, which curve each spring uses) and a flat *parameter vector* holding every number a
study may vary. A batch of variants is a parameter matrix ``P`` of shape ``(n_params, V)``;
:func:`crashstudy.arrays.batch.build_batch` turns it into the kernel's arrays. Study axes address the
vector through :attr:`Topology.paths` (dotted model path -> slots).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from crashstudy.vocabulary.codes import HISTORY_ORDER, PM_CODES
from crashstudy.vocabulary.materials import BY_NAME

if TYPE_CHECKING:  # a Topology (unpickled by a --jobs worker) needs no pydantic
    from crashstudy.schema.model import Model

TIME_STEP_MODES = ("safety_factor", "dt", "tolerance")


@dataclass(frozen=True)
class PathRef:
    """How a study axis acts on the parameter vector.

    ``op`` is ``"set"`` (the value replaces each slot), ``"scale"`` (multiplies each slot) or
    ``"speed"`` (``impact_velocity``: rescales each node's initial velocity vector to this speed).
    """

    op: str
    slots: tuple[int, ...]
    group: int = 1


@dataclass(frozen=True)
class MetricSpec:
    """One ``metrics:`` entry: node index, unit direction (None: the node's initial velocity direction,
    x when it has none), SAE J211 channel class and the criteria asked for."""

    node: int
    direction: tuple[float, ...] | None
    cfc: int
    criteria: tuple[str, ...]


@dataclass(frozen=True)
class Topology:
    """Everything the variants of one study share. Arrays are small and read-only."""

    name: str
    units: str
    dim: int
    node_ids: tuple[str, ...]
    spring_ids: tuple[str, ...]
    curve_ids: tuple[str, ...]
    wall_ids: tuple[str, ...]
    spring_nodes: np.ndarray  # (S, 2) int64
    material: np.ndarray  # (S,) int64 material code
    spring_curves: np.ndarray  # (S, 2) int64 curve index (loading/curve, unloading), -1 if none
    curve_offsets: np.ndarray  # (C + 1,) int64 into the flat knot arrays
    fixed: np.ndarray  # (N, D) bool
    load_node: np.ndarray  # (L,) int64
    load_curve: np.ndarray  # (L,) int64, -1 = constant
    pm_node: np.ndarray  # (P,) int64
    pm_dir: np.ndarray  # (P,) int64 axis
    pm_kind: np.ndarray  # (P,) int64 PM_*
    pm_curve: np.ndarray  # (P,) int64
    wall_nodes: np.ndarray  # (W, N) bool
    has_gravity: bool
    time_step_mode: str
    output_interval: float | None
    histories: tuple[str, ...]
    termination: bool
    accuracy_check: bool
    blocks: dict[str, slice] = field(repr=False)
    paths: dict[str, PathRef] = field(repr=False)
    n_params: int = 0
    metrics: tuple[MetricSpec, ...] = ()
    extra_histories: tuple[str, ...] = ()  # histories made after the kernel ("filtered_acceleration")
    # rate_elastic: the curves of every spring in rate order (R,) and each spring's range in them (S + 1,);
    # their rates are parameter block "rate"
    rate_curves: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64), repr=False)
    rate_offsets: np.ndarray | None = field(default=None, repr=False)

    @property
    def metric_nodes(self) -> tuple[int, ...]:
        """Nodes whose acceleration the kernel records at every step, in first-use order."""
        return tuple(dict.fromkeys(mt.node for mt in self.metrics))

    @property
    def n_nodes(self) -> int:
        return len(self.node_ids)

    @property
    def n_springs(self) -> int:
        return len(self.spring_ids)


ALL_HISTORIES = HISTORY_ORDER


def _fixed_axes(fixed: bool | Sequence[str], dim: int) -> list[bool]:
    axes = ["x", "y"][:dim]
    if fixed is True:
        return [True] * dim
    if fixed is False:
        return [False] * dim
    return [a in fixed for a in axes]


def compile_model(m: Model) -> tuple[Topology, np.ndarray]:
    """Compile a validated model into its topology and base parameter vector ``(n_params,)``."""
    dim = len(next(iter(m.nodes.values())).position)
    node_ids = tuple(m.nodes)
    spring_ids = tuple(m.springs)
    curve_ids = tuple(m.curves)
    nidx = {n: i for i, n in enumerate(node_ids)}
    cidx = {c: i for i, c in enumerate(curve_ids)}
    N, S, D = len(node_ids), len(spring_ids), dim
    L, P, W = len(m.loads), len(m.prescribed_motion), len(m.rigid_walls)
    lengths = [len(c.x) for c in m.curves.values()]
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    ptot = int(offsets[-1])
    C = len(curve_ids)
    rate_lists = [
        getattr(sp.material, BY_NAME[sp.material.type].rate_curves or "", None) or []
        for sp in m.springs.values()
    ]
    rate_offsets = np.concatenate([[0], np.cumsum([len(r) for r in rate_lists])]).astype(np.int64)

    sizes = [
        ("mass", N),
        ("position", N * D),
        ("velocity", N * D),
        ("k", S),
        ("ty", S),
        ("cy", S),
        ("cx", ptot),
        ("cy_", ptot),
        ("gravity", D),
        ("load", L * D),
        ("pm_scale", P),
        ("wall_point", W * D),
        ("wall_normal", W * D),
        ("wall_k", W),
        ("end_time", 1),
        ("time_step", 1),
        ("ke_fraction", 1),
        ("min_time", 1),
        ("kt", S),
        ("fy", S),
        ("e0", S),
        ("fail_t", S),
        ("fail_c", S),
        ("cfac", 2 * C),
        ("rate", int(rate_offsets[-1])),
    ]
    blocks: dict[str, slice] = {}
    pos = 0
    for name, n in sizes:
        blocks[name] = slice(pos, pos + n)
        pos += n
    p = np.zeros(pos)
    paths: dict[str, PathRef] = {}

    def put(block: str, offset: int, value: float, path: str | None) -> int:
        slot = blocks[block].start + offset
        p[slot] = value
        if path is not None:
            paths[path] = PathRef("set", (slot,))
        return slot

    axes = "xy"
    fixed = np.zeros((N, D), dtype=bool)
    for i, (nid, node) in enumerate(m.nodes.items()):
        put("mass", i, node.mass if node.mass is not None else 0.0, f"nodes.{nid}.mass")
        fixed[i] = _fixed_axes(node.fixed, D)
        for d in range(D):
            put("position", i * D + d, node.position[d], f"nodes.{nid}.position.{d}")
    speed_slots: list[int] = []
    for nid, v in m.initial_velocity.items():
        i = nidx[nid]
        for d in range(D):
            speed_slots.append(put("velocity", i * D + d, v[d], f"initial_velocity.{nid}.{d}"))
    paths["impact_velocity"] = PathRef("speed", tuple(speed_slots), D)

    spring_nodes = np.zeros((S, 2), dtype=np.int64)
    material = np.zeros(S, dtype=np.int64)
    spring_curves = -np.ones((S, 2), dtype=np.int64)
    for s, (sid, sp) in enumerate(m.springs.items()):
        spring_nodes[s] = [nidx[sp.nodes[0]], nidx[sp.nodes[1]]]
        mat = sp.material
        row = BY_NAME[mat.type]  # the material table: its code, parameter slots and curve roles
        material[s] = row.code
        base = f"springs.{sid}.material"
        put("ty", s, np.inf, None)
        put("cy", s, -np.inf, None)
        for slot in row.slots:
            value = getattr(mat, slot.field)
            if value is None:  # an optional field left out (a required one is never None)
                assert slot.absent is not None
                value = slot.absent
            put(slot.block, s, value, f"{base}.{slot.field}")
        for r, role in enumerate(row.curves):
            spring_curves[s, r] = cidx[getattr(mat, role.field)]
        for k, rc in enumerate(rate_lists[s]):  # rate_elastic: curve_a is the first (rate-0) curve
            put("rate", int(rate_offsets[s]) + k, rc.rate, f"{base}.curves.{k}.rate")
            spring_curves[s, 0] = spring_curves[s, 0] if k else cidx[rc.curve]
        # spring options: preload / free length and failure elongations (inf: never breaks)
        put("e0", s, sp.initial_elongation, None if row.by_rate else f"springs.{sid}.initial_elongation")
        fail = sp.failure
        put(
            "fail_t",
            s,
            fail.tension if fail is not None and fail.tension is not None else np.inf,
            f"springs.{sid}.failure.tension",
        )
        put(
            "fail_c",
            s,
            fail.compression if fail is not None and fail.compression is not None else -np.inf,
            f"springs.{sid}.failure.compression",
        )

    for c, (cid, curve) in enumerate(m.curves.items()):
        o = int(offsets[c])
        xs, ys = [], []
        for k, (x, y) in enumerate(zip(curve.x, curve.y, strict=False)):  # lengths checked by the schema
            xs.append(put("cx", o + k, x, f"curves.{cid}.x.{k}"))
            ys.append(put("cy_", o + k, y, f"curves.{cid}.y.{k}"))
        # a curve's force and abscissa scales are one factor each per variant (arrays.batch.curve_points):
        # the points stay the curve's shape, so a study scaling a curve keeps one ramp for all variants
        paths[f"curves.{cid}.scale"] = PathRef("scale", (put("cfac", 2 * c, 1.0, None),))
        paths[f"curves.{cid}.x_scale"] = PathRef("scale", (put("cfac", 2 * c + 1, 1.0, None),))

    if m.gravity is not None:
        for d in range(D):
            put("gravity", d, m.gravity[d], f"gravity.{d}")
    load_node = np.array([nidx[ld.node] for ld in m.loads], dtype=np.int64)
    load_curve = np.array([cidx[ld.curve] if ld.curve else -1 for ld in m.loads], dtype=np.int64)
    for i, ld in enumerate(m.loads):
        for d in range(D):
            put("load", i * D + d, ld.force[d], f"loads.{i}.force.{d}")
    kinds = PM_CODES
    pm = m.prescribed_motion
    for i, q in enumerate(pm):
        put("pm_scale", i, q.scale, f"prescribed_motion.{i}.scale")
    wall_nodes = np.zeros((W, N), dtype=bool)
    for i, w in enumerate(m.rigid_walls):
        wall_nodes[i] = True if w.nodes is None else [n in w.nodes for n in node_ids]
        for d in range(D):
            put("wall_point", i * D + d, w.point[d], f"rigid_walls.{i}.point.{d}")
            put("wall_normal", i * D + d, w.normal[d], f"rigid_walls.{i}.normal.{d}")
        put(
            "wall_k", i, w.stiffness or 0.0, f"rigid_walls.{i}.stiffness" if w.stiffness is not None else None
        )
    put("end_time", 0, m.end_time, "end_time")
    mode = m.time_step.mode
    put("time_step", 0, getattr(m.time_step, mode), f"time_step.{mode}")
    term = m.termination
    put(
        "ke_fraction",
        0,
        term.kinetic_energy_fraction if term else 0.0,
        "termination.kinetic_energy_fraction" if term else None,
    )
    put("min_time", 0, term.min_time if term else 0.0, "termination.min_time" if term else None)

    hist = m.output.histories
    histories = ALL_HISTORIES if hist == "all" else () if hist == "none" else tuple(hist)
    if not m.rigid_walls:
        histories = tuple(h for h in histories if h != "wall_force")
    keep = hist == "all" or (isinstance(hist, list) and "filtered_acceleration" in hist)
    extra = ("filtered_acceleration",) if m.metrics and keep else ()
    histories = tuple(h for h in histories if h != "filtered_acceleration")
    metrics = tuple(
        MetricSpec(nidx[mt.node], _unit(mt.direction, D), mt.cfc, tuple(mt.criteria)) for mt in m.metrics
    )
    topo = Topology(
        name=m.name,
        units=m.units,
        dim=D,
        node_ids=node_ids,
        spring_ids=spring_ids,
        curve_ids=curve_ids,
        wall_ids=tuple(w.id for w in m.rigid_walls),
        spring_nodes=spring_nodes,
        material=material,
        spring_curves=spring_curves,
        curve_offsets=offsets,
        fixed=fixed,
        load_node=load_node,
        load_curve=load_curve,
        pm_node=np.array([nidx[q.node] for q in pm], dtype=np.int64),
        pm_dir=np.array([axes.index(q.direction) for q in pm], dtype=np.int64),
        pm_kind=np.array([kinds[q.quantity] for q in pm], dtype=np.int64),
        pm_curve=np.array([cidx[q.curve] for q in pm], dtype=np.int64),
        wall_nodes=wall_nodes,
        has_gravity=m.gravity is not None and any(m.gravity),
        time_step_mode=mode,
        output_interval=m.output.interval,
        histories=histories,
        termination=term is not None,
        accuracy_check=m.accuracy_check,
        blocks=blocks,
        paths=paths,
        n_params=pos,
        metrics=metrics,
        extra_histories=extra,
        rate_curves=np.array([cidx[rc.curve] for r in rate_lists for rc in r], dtype=np.int64),
        rate_offsets=rate_offsets,
    )
    return topo, p


def _unit(direction: str | Sequence[float] | None, dim: int) -> tuple[float, ...] | None:
    """A metric's direction as a unit vector of ``dim`` components (None: from the initial velocity)."""
    if direction is None:
        return None
    vec = np.array(
        [1.0 if a == direction else 0.0 for a in "xy"[:dim]] if isinstance(direction, str) else direction
    )
    return tuple(float(c) for c in vec / np.sqrt(np.sum(vec * vec)))


def apply_axis(P: np.ndarray, ref: PathRef, values: np.ndarray) -> None:
    """Apply one study axis to the parameter matrix ``P`` (n_params, V) in place.

    ``values`` has shape ``(V,)``: the axis value of each variant.
    """
    idx = list(ref.slots)
    with np.errstate(
        over="ignore", invalid="ignore"
    ):  # a value that overflows is refused by the study's check
        _apply(P, ref, idx, values)


def _apply(P: np.ndarray, ref: PathRef, idx: list[int], values: np.ndarray) -> None:
    if ref.op == "set":
        P[idx, :] = values[None, :]
    elif ref.op == "scale":
        P[idx, :] *= values[None, :]
    elif ref.op == "speed":
        # slots come in groups of `group` (the model's dimension): one group per node
        for g in range(0, len(idx), ref.group):
            rows = idx[g : g + ref.group]
            sub = P[rows, :]
            speed = np.sqrt(np.sum(sub * sub, axis=0))
            factor = np.divide(values, speed, out=np.zeros_like(speed), where=speed > 0)
            P[rows, :] = sub * factor[None, :]
    else:  # pragma: no cover - PathRef is built here only
        raise ValueError(ref.op)
