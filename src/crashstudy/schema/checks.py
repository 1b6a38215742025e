"""Checks of relations between entries of a model (things one field alone cannot tell).

Each check yields ``(path, message)`` where ``path`` is the tuple of keys/indices of the offending
field in the YAML document, so the caller can name its line.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np

from crashstudy.schema.model import (
    DAMPER_TYPES,
    Crush,
    GeneralNonlinear,
    Model,
    NonlinearDamper,
    RateElastic,
    RigidWall,
    Spring,
)
from crashstudy.schema.signs import (
    SIGNED_TYPES,
    behind_message,
    depth_behind_walls,
    sign_message,
    wrong_sign_points,
)
from crashstudy.units import UNIT_SYSTEMS

Path = tuple[str | int, ...]
Found = Iterator[tuple[Path, str]]


def curve_value(x: list[float], y: list[float], at: float) -> float:
    """Piecewise-linear curve value at ``at`` with linear extrapolation along the end segments."""
    xs, ys = np.asarray(x), np.asarray(y)
    if at <= xs[0]:
        return float(ys[0] + (ys[1] - ys[0]) / (xs[1] - xs[0]) * (at - xs[0]))
    if at >= xs[-1]:
        return float(ys[-1] + (ys[-1] - ys[-2]) / (xs[-1] - xs[-2]) * (at - xs[-1]))
    return float(np.interp(at, xs, ys))


def model_problems(m: Model) -> list[tuple[Path, str]]:
    """All relational problems of a shape-valid model, in file order."""
    dim = len(next(iter(m.nodes.values())).position)
    out: list[tuple[Path, str]] = []
    for check in (_nodes, _springs, _vectors, _loads_and_motion, _walls, _output, _metrics, _iso_mme):
        out.extend(check(m, dim))
    return out


def _fixed_axes(fixed: bool | Sequence[str], dim: int) -> set[str]:
    axes = ["x", "y"][:dim]
    if fixed is True:
        return set(axes)
    if fixed is False:
        return set()
    return set(fixed)


def _nodes(m: Model, dim: int) -> Found:
    for nid, node in m.nodes.items():
        if len(node.position) != dim:
            yield (
                ("nodes", nid, "position"),
                (
                    f"expected {dim} coordinate(s) like the first node (a model is 1-D or 2-D throughout), "
                    f"got {len(node.position)}"
                ),
            )
        fixed = _fixed_axes(node.fixed, dim)
        if dim == 1 and "y" in fixed:
            yield ("nodes", nid, "fixed"), "a 1-D model has only the axis 'x'"
        if len(fixed) < dim and node.mass is None:
            yield ("nodes", nid), "a node that is not fixed in every direction needs 'mass' > 0"


def _curve_ref(m: Model, path: Path, cid: str) -> Found:
    if cid not in m.curves:
        yield path, f"unknown curve {cid!r}; defined curves: {sorted(m.curves) or 'none'}"


def _springs(m: Model, dim: int) -> Found:
    for sid, sp in m.springs.items():
        a, b = sp.nodes
        for k, nid in enumerate(sp.nodes):
            if nid not in m.nodes:
                yield ("springs", sid, "nodes", k), f"unknown node {nid!r}"
        if a == b:
            yield ("springs", sid, "nodes"), "a spring joins two different nodes"
        elif a in m.nodes and b in m.nodes:
            pa, pb = m.nodes[a].position, m.nodes[b].position
            if len(pa) == len(pb) and float(np.hypot.reduce(np.subtract(pb, pa))) == 0.0:
                yield (
                    ("springs", sid, "nodes"),
                    f"nodes {a!r} and {b!r} are at the same position: a spring needs a non-zero initial length",
                )
        yield from _material(m, sid, sp)


def origin_message(cid: str, key: str, at0: float, damper: bool) -> str:
    """Why a material curve must pass through the origin, and what to write instead."""
    if damper:
        return (
            f"the damper curve {cid!r} must pass through the origin (its force at rate 0 is {at0:g}): a damper carries "
            "no force at rest; a preload belongs on a spring, with initial_elongation"
        )
    label = "curve" if key == "curve" else f"{key} curve"
    return (
        f"the {label} {cid!r} must pass through the origin (its force at e=0 is {at0:g}): a spring that "
        "carries force at t = 0 says so with initial_elongation (shift the curve through (0, 0) and set "
        "initial_elongation to the elongation of the preload), never with a shifted curve"
    )


def _material(m: Model, sid: str, sp: Spring) -> Found:
    mat = sp.material
    base: Path = ("springs", sid, "material")
    refs: list[tuple[Path, str, str]] = [
        (base + (k,), k, getattr(mat, k)) for k in ("curve", "loading", "unloading") if hasattr(mat, k)
    ]
    if isinstance(mat, RateElastic):  # a list of {rate, curve}: each curve is an elastic curve of its own
        refs = [(base + ("curves", i, "curve"), "curve", rc.curve) for i, rc in enumerate(mat.curves)]
    for path, _key, cid in refs:
        yield from _curve_ref(m, path, cid)
    signed = mat.type in SIGNED_TYPES or isinstance(mat, RateElastic)
    for path, key, cid in refs:  # every material curve passes through the origin (SPEC: initial_elongation)
        if cid in m.curves:
            c = m.curves[cid]
            scale = max(abs(v) for v in c.y) or 1.0
            at0 = curve_value(c.x, c.y, 0.0)
            if abs(at0) > 1e-9 * scale:
                yield path, origin_message(cid, key, at0, mat.type in DAMPER_TYPES)
            elif key != "unloading" and signed:  # force of the sign of the elongation
                bad = np.flatnonzero(
                    wrong_sign_points(np.asarray(c.x)[:, None], np.asarray(c.y)[:, None])[:, 0]
                )
                if bad.size:
                    k = int(bad[0])
                    use = mat.type if key == "curve" else f"{mat.type} {key}"
                    yield path, sign_message(cid, k, c.x[k], c.y[k], use)
    if isinstance(mat, GeneralNonlinear) and mat.unloading in m.curves:
        c = m.curves[mat.unloading]
        if any(not b > a for a, b in zip(c.y, c.y[1:], strict=False)):
            yield (
                base + ("unloading",),
                f"the unloading curve {mat.unloading!r} must be increasing (y strictly increasing)",
            )
    elif isinstance(mat, NonlinearDamper) and mat.curve in m.curves:
        c = m.curves[mat.curve]
        if any(b < a for a, b in zip(c.y, c.y[1:], strict=False)):
            yield (
                base + ("curve",),
                f"the damper curve {mat.curve!r} must be increasing (y non-decreasing with the rate)",
            )
    elif isinstance(mat, Crush) and mat.loading in m.curves:
        c = m.curves[mat.loading]
        if c.x[0] >= 0:
            yield base + ("loading",), f"the crush curve {mat.loading!r} needs a compression part (x < 0)"
        elif not any(y < 0 for x, y in zip(c.x, c.y, strict=False) if x < 0):
            yield (
                base + ("loading",),
                (
                    f"the crush curve {mat.loading!r} has no negative force in compression (x < 0): a crush spring "
                    "carries min(0, curve), so it would carry no force; compression forces are negative"
                ),
            )
    e0 = sp.initial_elongation
    if e0 != 0.0 and mat.type in DAMPER_TYPES:
        yield (
            ("springs", sid, "initial_elongation"),
            (
                f"a {mat.type} has no initial elongation (its force follows the elongation rate); remove "
                "initial_elongation, or put the preload on a spring in parallel"
            ),
        )
    fail = sp.failure
    if fail is not None:
        if fail.tension is not None and not e0 < fail.tension:
            yield (
                ("springs", sid, "failure", "tension"),
                (
                    f"expected a tension failure elongation above initial_elongation ({e0:g}), got {fail.tension:g}: "
                    "the spring would be broken at t = 0"
                ),
            )
        if fail.compression is not None and not e0 > fail.compression:
            yield (
                ("springs", sid, "failure", "compression"),
                (
                    f"expected a compression failure elongation below initial_elongation ({e0:g}), got "
                    f"{fail.compression:g}: the spring would be broken at t = 0"
                ),
            )


def _vectors(m: Model, dim: int) -> Found:
    for nid, v in m.initial_velocity.items():
        if nid not in m.nodes:
            yield ("initial_velocity", nid), f"unknown node {nid!r}"
            continue
        if len(v) != dim:
            yield ("initial_velocity", nid), f"expected {dim} component(s), got {len(v)}"
            continue
        fixed = _fixed_axes(m.nodes[nid].fixed, dim)
        for k, ax in enumerate(["x", "y"][:dim]):
            if ax in fixed and v[k] != 0.0:
                yield (
                    ("initial_velocity", nid, k),
                    f"node {nid!r} is fixed along {ax}; its initial velocity there must be 0",
                )
    if m.gravity is not None and len(m.gravity) != dim:
        yield ("gravity",), f"expected {dim} component(s), got {len(m.gravity)}"


def _loads_and_motion(m: Model, dim: int) -> Found:
    for i, ld in enumerate(m.loads):
        if ld.node not in m.nodes:
            yield ("loads", i, "node"), f"unknown node {ld.node!r}"
        if len(ld.force) != dim:
            yield ("loads", i, "force"), f"expected {dim} component(s), got {len(ld.force)}"
        if ld.curve is not None:
            yield from _curve_ref(m, ("loads", i, "curve"), ld.curve)
    seen: dict[tuple[str, str], int] = {}
    for i, pm in enumerate(m.prescribed_motion):
        path: Path = ("prescribed_motion", i)
        yield from _curve_ref(m, path + ("curve",), pm.curve)
        if pm.node not in m.nodes:
            yield path + ("node",), f"unknown node {pm.node!r}"
            continue
        if dim == 1 and pm.direction == "y":
            yield path + ("direction",), "a 1-D model has only the direction 'x'"
        elif pm.direction in _fixed_axes(m.nodes[pm.node].fixed, dim):
            yield (
                path + ("direction",),
                f"node {pm.node!r} is fixed along {pm.direction}: a prescribed direction must not also be fixed",
            )
        key = (pm.node, pm.direction)
        if key in seen:
            yield (
                path,
                f"node {pm.node!r} already has a prescribed motion along {pm.direction} (entry {seen[key]})",
            )
        seen[key] = i


def _walls(m: Model, dim: int) -> Found:
    ids: set[str] = set()
    for i, w in enumerate(m.rigid_walls):
        path: Path = ("rigid_walls", i)
        if w.id in ids:
            yield path + ("id",), f"duplicate wall id {w.id!r}"
        ids.add(w.id)
        for key in ("point", "normal"):
            if len(getattr(w, key)) != dim:
                yield path + (key,), f"expected {dim} component(s), got {len(getattr(w, key))}"
        if not any(w.normal):
            yield path + ("normal",), "the normal must not be the zero vector"
        for k, nid in enumerate(w.nodes or []):
            if nid not in m.nodes:
                yield path + ("nodes", k), f"unknown node {nid!r}"
        yield from _wall_and_motion(m, dim, i, w)
    yield from _behind_walls(m, dim)


def _behind_walls(m: Model, dim: int) -> Found:
    """A node a wall stops starts on the wall's front side (:func:`~crashstudy.schema.signs.depth_behind_walls`)."""
    walls = [(i, w) for i, w in enumerate(m.rigid_walls) if len(w.point) == dim and len(w.normal) == dim]
    if not walls or any(len(n.position) != dim for n in m.nodes.values()):
        return
    ids = list(m.nodes)
    x = np.array([n.position for n in m.nodes.values()], dtype=np.float64)[:, :, None]
    free = np.array([[ax not in _fixed_axes(n.fixed, dim) for ax in "xy"[:dim]] for n in m.nodes.values()])
    point = np.array([w.point for _, w in walls], dtype=np.float64)[:, :, None]
    normal = np.array([w.normal for _, w in walls], dtype=np.float64)[:, :, None]
    held = np.array([[w.nodes is None or nid in w.nodes for nid in ids] for _, w in walls])
    depth = depth_behind_walls(x, free, point, normal, held)[:, :, 0]
    for (i, w), row in zip(walls, depth, strict=True):
        bad = np.flatnonzero(row > 0)
        if bad.size:
            k = int(bad[0])
            yield (
                ("rigid_walls", i, "point"),
                behind_message(ids[k], float(row[k]), w.id, UNIT_SYSTEMS[m.units].length, bad.size - 1),
            )


def _wall_and_motion(m: Model, dim: int, i: int, w: RigidWall) -> Found:
    """A wall must not hold a node along a direction that a prescribed motion drives.

    The motion fixes the node's velocity along its direction at every step; the wall would remove the
    velocity into the wall. Both cannot hold: the kernel let the motion win (the node went through the
    wall while the wall force grew without bound). A wall whose normal is across the driven direction
    (a floor under a node driven along it) does not touch the driven velocity and is allowed.
    """
    held = list(m.nodes) if w.nodes is None else w.nodes
    axes = ["x", "y"][:dim]
    for j, pm in enumerate(m.prescribed_motion):
        if pm.node not in held or pm.direction not in axes or len(w.normal) != dim:
            continue
        if w.normal[axes.index(pm.direction)] == 0.0:
            continue
        where: Path = ("rigid_walls", i) + (("nodes", w.nodes.index(pm.node)) if w.nodes is not None else ())
        yield (
            where,
            (
                f"wall {w.id!r} holds node {pm.node!r}, which prescribed_motion.{j} drives along {pm.direction} "
                f"(into or away from the wall): a node cannot both follow a prescribed motion and be stopped by a wall; "
                + (
                    "remove the node from the wall's nodes"
                    if w.nodes is not None
                    else "list the nodes the wall stops (nodes: [...]) without it"
                )
                + " or drive another node"
            ),
        )


def _output(m: Model, dim: int) -> Found:
    if m.output.interval is not None and m.output.interval > m.end_time:
        yield (
            ("output", "interval"),
            f"expected an interval no longer than end_time ({m.end_time:g}), got {m.output.interval:g}",
        )
    if not m.rigid_walls and isinstance(m.output.histories, list) and "wall_force" in m.output.histories:
        yield ("output", "histories"), "'wall_force' needs at least one rigid wall"


def _metrics(m: Model, dim: int) -> Found:
    """A metric names a node that moves, a direction of the model's dimension that is not zero, and each
    criterion of a node once (a criterion is one summary value per node)."""
    seen: dict[tuple[str, str], int] = {}
    for i, mt in enumerate(m.metrics):
        path: Path = ("metrics", i)
        if mt.node not in m.nodes:
            yield path + ("node",), f"unknown node {mt.node!r}; nodes: {', '.join(sorted(m.nodes))}"
        elif len(_fixed_axes(m.nodes[mt.node].fixed, dim)) == dim:
            yield (
                path + ("node",),
                f"node {mt.node!r} is fixed in every direction: it has no acceleration to judge",
            )
        d = mt.direction
        if isinstance(d, str):
            if dim == 1 and d == "y":
                yield path + ("direction",), "a 1-D model has only the direction 'x'"
        elif d is not None:
            if len(d) != dim:
                yield (
                    path + ("direction",),
                    f"expected {dim} component(s) (the model is {dim}-D), got {len(d)}",
                )
            elif not any(d):
                yield path + ("direction",), "the direction must not be the zero vector"
        for k, c in enumerate(mt.criteria):
            key = (mt.node, c)
            if key in seen:
                where = "this entry" if seen[key] == i else f"metrics.{seen[key]}"
                yield (
                    path + ("criteria", k),
                    f"criterion {c!r} of node {mt.node!r} is already asked for in {where}",
                )
            else:
                seen[key] = i
    if (
        not m.metrics
        and isinstance(m.output.histories, list)
        and "filtered_acceleration" in m.output.histories
    ):
        yield (
            ("output", "histories"),
            "'filtered_acceleration' needs a metrics: block (it is the filtered pulse of its nodes)",
        )


def raw_reference_problems(data: object) -> list[tuple[Path, str]]:
    """Unknown node and curve names, read from plain data that failed shape validation.

    With a shape error no :class:`Model` exists, but a misspelled reference elsewhere in the file is
    still worth reporting in the same run; every lookup here is defensive.
    """
    if not isinstance(data, dict):
        return []
    nodes: dict[str, Any] = data["nodes"] if isinstance(data.get("nodes"), dict) else {}
    curves: dict[str, Any] = data["curves"] if isinstance(data.get("curves"), dict) else {}
    out: list[tuple[Path, str]] = []

    def node_ref(path: Path, name: object) -> None:
        if isinstance(name, str) and nodes and name not in nodes:
            out.append((path, f"unknown node {name!r}"))

    def curve_ref(path: Path, name: object) -> None:
        if isinstance(name, str) and name not in curves:
            out.append((path, f"unknown curve {name!r}; defined curves: {sorted(curves) or 'none'}"))

    springs = data.get("springs")
    for sid, sp in springs.items() if isinstance(springs, dict) else []:
        if not isinstance(sp, dict):
            continue
        ends = sp.get("nodes")
        for k, nid in enumerate(ends if isinstance(ends, list) else []):
            node_ref(("springs", sid, "nodes", k), nid)
        mat = sp.get("material")
        if isinstance(mat, dict):
            for key in ("curve", "loading", "unloading"):
                if key in mat:
                    curve_ref(("springs", sid, "material", key), mat[key])
    for key in ("loads", "prescribed_motion", "metrics"):
        items = data.get(key)
        for i, item in enumerate(items if isinstance(items, list) else []):
            if isinstance(item, dict):
                node_ref((key, i, "node"), item.get("node"))
                if item.get("curve") is not None:
                    curve_ref((key, i, "curve"), item.get("curve"))
    iv = data.get("initial_velocity")
    for nid in iv if isinstance(iv, dict) else {}:
        node_ref(("initial_velocity", nid), nid)
    walls = data.get("rigid_walls")
    for i, w in enumerate(walls if isinstance(walls, list) else []):
        ids = w.get("nodes") if isinstance(w, dict) else None
        for k, nid in enumerate(ids if isinstance(ids, list) else []):
            node_ref(("rigid_walls", i, "nodes", k), nid)
    return out


def _iso_mme(m: Model, dim: int) -> Found:
    """Each ``iso_mme`` key is a node or spring id, and no two items share a code prefix (their channels
    would get the same codes)."""
    seen: dict[str, str] = {}
    for key, prefix in m.iso_mme.items():
        if key not in m.nodes and key not in m.springs:
            yield (
                ("iso_mme", key),
                (
                    f"unknown id {key!r}: expected a node or spring id (nodes: "
                    f"{', '.join(list(m.nodes)[:6])}; springs: {', '.join(list(m.springs)[:6])})"
                ),
            )
        elif prefix in seen:
            yield ("iso_mme", key), f"code {prefix} is already {seen[prefix]!r}'s: each id needs its own"
        seen.setdefault(prefix, key)
