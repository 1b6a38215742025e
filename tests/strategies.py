"""Hypothesis strategies of random valid inputs (tests/test_properties_*.py, tests/test_invariants.py): models
of 2-6 nodes in 1-D and 2-D trees, every material of the generator, walls, loads, gravity, preloads and
three unit systems, with the curves they need."""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st

NAMES = ["a", "b", "c", "d", "e", "f"]


def examples(default: int, explore: int) -> int:
    """``max_examples`` of a property test: ``default`` under the default profile (conftest.py: derandomized,
    the same examples on every run, kept few so the suite stays fast), ``explore`` under
    ``HYPOTHESIS_PROFILE=explore`` (new random examples on every run, as many as the counts in
    docs/robustness.md were taken with)."""
    return explore if os.environ.get("HYPOTHESIS_PROFILE") == "explore" else default


def num(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


@st.composite
def increasing(draw: st.DrawFn, n: int, lo: float, hi: float, min_gap: float) -> list[float]:
    """``n`` strictly increasing values in [lo, hi] at least ``min_gap`` apart (rounded, as a user writes)."""
    gaps = draw(st.lists(num(min_gap, (hi - lo) / max(n, 1)), min_size=n, max_size=n))
    out, x = [], lo
    for g in gaps:
        x += g
        out.append(round(x, 6))
    for a, b in zip(out, out[1:], strict=False):
        assume(b > a)
    return out


@st.composite
def force_curve(
    draw: st.DrawFn,
    through_origin: bool,
    need_compression: bool = False,
    increasing_y: bool = False,
    kmax: float = 1e5,
    signed: bool = False,
) -> dict[str, list[float]]:
    """A material curve (elongation -> force): compression knots, the origin, tension knots."""
    n_neg = draw(st.integers(1 if need_compression or through_origin else 0, 3))
    n_pos = draw(st.integers(1 if through_origin or n_neg == 0 else 0, 3))
    neg = [-v for v in reversed(draw(increasing(n_neg, 0.0, 0.5, 0.005)))]
    pos = draw(increasing(n_pos, 0.0, 0.5, 0.005))
    xs = neg + [0.0] + pos
    ys = [0.0]
    # walk away from the origin in both directions with bounded slopes
    for direction, knots in ((-1, neg[::-1]), (1, pos)):
        prev_x, prev_y, side = 0.0, 0.0, []
        for x in knots:
            lo = 0.02 * kmax if increasing_y else -kmax
            slope = draw(num(lo, kmax))
            prev_y = round(prev_y + slope * (x - prev_x), 6)
            if signed:  # force of the sign of the elongation (validate refuses a negative stiffness)
                prev_y = max(prev_y, 0.0) if direction > 0 else min(prev_y, 0.0)
            prev_x = x
            side.append(prev_y)
        ys = side[::-1] + ys if direction < 0 else ys + side
    if increasing_y:
        assume(all(b > a for a, b in zip(ys, ys[1:], strict=False)))
    if need_compression:  # a crush curve must push in compression (validate refuses one that cannot)
        assume(any(y < 0 for x, y in zip(xs, ys, strict=True) if x < 0))
    if not through_origin:
        shift = draw(num(-0.1 * kmax, 0.1 * kmax))
        ys = [round(y + shift, 6) for y in ys]
    return {"x": xs, "y": ys}


@st.composite
def time_curve(draw: st.DrawFn, end_time: float) -> dict[str, list[float]]:
    n = draw(st.integers(2, 4))
    xs = draw(increasing(n, -0.1 * end_time, 1.2 * end_time, end_time / 50))
    ys = draw(st.lists(num(-2.0, 2.0).map(lambda v: round(v, 4)), min_size=n, max_size=n))
    return {"x": xs, "y": ys}


@st.composite
def valid_model(draw: st.DrawFn) -> dict[str, Any]:
    dim = draw(st.sampled_from([1, 2]))
    n = draw(st.integers(2, 6))
    ids = NAMES[:n]
    root_fixed = draw(st.booleans()) or draw(st.booleans())  # 3/4 of the models hang on a fixed node
    end_time = draw(num(1e-3, 0.03).map(lambda v: round(v, 5)))
    curves: dict[str, Any] = {}
    nodes: dict[str, Any] = {}
    positions: list[list[float]] = []
    for k, nid in enumerate(ids):
        if k == 0:
            pos = [0.0] * dim
        else:
            parent = positions[draw(st.integers(0, k - 1))] if draw(st.booleans()) else positions[k - 1]
            length = draw(num(0.05, 1.0))
            if dim == 1:
                pos = [round(parent[0] + draw(st.sampled_from([-1, 1])) * length, 6)]
            else:
                ang = draw(num(0.0, 2 * math.pi))
                pos = [
                    round(parent[0] + length * math.cos(ang), 6),
                    round(parent[1] + length * math.sin(ang), 6),
                ]
        positions.append(pos)
        node: dict[str, Any] = {"position": pos}
        if k == 0 and root_fixed:
            node["fixed"] = True
        else:
            node["mass"] = round(draw(num(0.1, 100.0)), 4)
            if dim == 2 and draw(st.integers(0, 4)) == 0:
                node["fixed"] = [draw(st.sampled_from(["x", "y"]))]
        nodes[nid] = node
    springs: dict[str, Any] = {}
    for k in range(1, n):
        # tree: node k hangs on an earlier node at a different position
        cands = [j for j in range(k) if positions[j] != positions[k]]
        assume(cands)
        j = draw(st.sampled_from(cands))
        kind = draw(
            st.sampled_from(["linear_elastic", "nonlinear_elastic", "general_nonlinear", "crush", "damper"])
        )
        kmax = draw(num(1e2, 1e5))
        if kind == "linear_elastic":
            mat: dict[str, Any] = {"type": kind, "stiffness": round(kmax, 3)}
        elif kind == "damper":
            mat = {"type": kind, "damping": round(draw(num(0.0, 100.0)), 3)}
        elif kind == "nonlinear_elastic":
            cid = f"c{k}"
            curves[cid] = draw(
                force_curve(through_origin=True, kmax=kmax, signed=True)
            )  # a preload: initial_elongation
            mat = {"type": kind, "curve": cid}
        elif kind == "crush":
            cid = f"c{k}"
            curves[cid] = draw(force_curve(through_origin=True, need_compression=True, kmax=kmax))
            mat = {"type": kind, "loading": cid, "unloading_stiffness": round(draw(num(1e2, 2e5)), 3)}
        else:
            lid, uid = f"l{k}", f"u{k}"
            curves[lid] = draw(force_curve(through_origin=True, kmax=kmax, signed=True))
            curves[uid] = draw(force_curve(through_origin=True, increasing_y=True, kmax=kmax))
            mat = {"type": kind, "loading": lid, "unloading": uid}
            if draw(st.booleans()):
                mat["tension_yield"] = round(draw(num(1.0, 1e4)), 3)
            if draw(st.booleans()):
                mat["compression_yield"] = -round(draw(num(1.0, 1e4)), 3)
        springs[f"s{k}"] = {
            "nodes": [ids[j], ids[k]] if draw(st.booleans()) else [ids[k], ids[j]],
            "material": mat,
        }
        if kind != "damper" and draw(st.integers(0, 3)) == 0:  # a preloaded spring (force at t = 0)
            springs[f"s{k}"]["initial_elongation"] = round(draw(num(-0.05, 0.05)), 4)
    free = [nid for nid in ids if nodes[nid].get("fixed") is not True]
    model: dict[str, Any] = {
        "name": "generated",
        "units": draw(st.sampled_from(["SI", "mm-ms-kg-kN", "mm-s-t-N"])),
        "curves": curves,
        "nodes": nodes,
        "springs": springs,
    }
    iv: dict[str, list[float]] = {}
    some = draw(st.sampled_from([1, 1, 1, 0]))  # 3 in 4 models start moving
    moving: list[str] = draw(st.lists(st.sampled_from(free), min_size=some, unique=True)) if free else []
    for nid in moving:
        fixed = nodes[nid].get("fixed") or []
        iv[nid] = [
            0.0 if ax in fixed else draw(st.sampled_from([-1, 1])) * round(draw(num(0.5, 20.0)), 3)
            for ax in "xy"[:dim]
        ]
    if iv and draw(st.sampled_from([False] * 7 + [True])):
        # an extreme but finite speed: the state overflows and the variant must fail with a reason
        nid = sorted(iv)[0]
        iv[nid] = [v * 10.0 ** draw(st.integers(150, 300)) for v in iv[nid]]
    if iv:
        model["initial_velocity"] = iv
    if draw(st.booleans()):
        model["gravity"] = [round(draw(num(-10.0, 10.0)), 3) for _ in range(dim)]
    with_loads: bool = draw(st.booleans())
    if free and with_loads:
        loads: list[dict[str, Any]] = []
        for _ in range(draw(st.integers(1, 2))):
            load: dict[str, Any] = {
                "node": draw(st.sampled_from(free)),
                "force": [round(draw(num(-1e3, 1e3)), 2) for _ in range(dim)],
            }
            if draw(st.booleans()):
                cid = f"t{len(loads)}"
                curves[cid] = draw(time_curve(end_time))
                load["curve"] = cid
            loads.append(load)
        model["loads"] = loads
    if draw(st.sampled_from([False, False, True])):
        normal = (
            [draw(st.sampled_from([-1.0, 1.0]))]
            if dim == 1
            else [round(draw(num(-1.0, 1.0)), 3) for _ in "xy"]
        )
        assume(any(normal))
        wall: dict[str, Any] = {
            "id": "wall",
            "point": [round(draw(num(-2.0, 2.0)), 3) for _ in range(dim)],
            "normal": normal,
        }
        if draw(st.booleans()):
            wall["nodes"] = draw(st.lists(st.sampled_from(ids), min_size=1, unique=True))
        # every node the wall stops starts on its front side (validate refuses one behind it): move the wall back
        unit = np.asarray(normal) / np.linalg.norm(normal)
        held = [positions[k] for k, nid in enumerate(ids) if nid in wall.get("nodes", ids)]
        behind = min(float(np.dot(np.subtract(x, wall["point"]), unit)) for x in held)
        if behind < 0:
            back = behind - draw(num(0.0, 0.5))
            wall["point"] = [
                float(round(p + back * u, 3) - 1e-3 * math.copysign(1.0, u))
                for p, u in zip(wall["point"], unit, strict=True)
            ]
        model["rigid_walls"] = [wall]
    model["end_time"] = end_time
    if draw(st.booleans()):
        model["time_step"] = {"safety_factor": round(draw(num(0.1, 1.0)), 4) or 1.0}
    else:
        model["time_step"] = {"tolerance": draw(st.sampled_from([1e-5, 1e-4, 1e-3, 1e-2, 0.1]))}
    model["output"] = {"histories": "none"}
    return model
