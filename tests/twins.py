"""The model builders of the bitwise twin tests: the same model run by the NumPy reference kernel and by
each fast kernel (tests/test_kernel_twins.py, tests/test_metrics.py's per-step record), shared with the
physics and knot-peak tests that check some of them against closed forms. ``CASES``: every twin case,
``case -> (model builder, study axes)``; :func:`record_case` gives a case's batch with the per-step
record of every movable node."""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np

from crashstudy.kernel.output import ALL_SHAPES, KernelOutput
from helpers import STUDIES, model_batch

G = 9.80665  # m/s^2
HELICOPTER = STUDIES / "models" / "helicopter-subfloor.yaml"
MASSES = [6.0, 8.0, 10.0, 12.0, 14.0]

# --------------------------------------------------------------------------------------------------
# the full twins (tests/test_physics.py's models): every material, walls, gravity, loads, prescribed motion
# --------------------------------------------------------------------------------------------------

TWIN_1D: dict[str, Any] = {  # crush, linear + damper, nonlinear, general_nonlinear; wall, gravity, load, pm
    "name": "twin-1d",
    "curves": {
        "plateau": {"x": [-1.0, -0.002, 0.0], "y": [-3000.0, -3000.0, 0.0]},
        "soft": {"x": [-0.1, -0.01, 0.0, 0.01, 0.1], "y": [-4000.0, -500.0, 0.0, 500.0, 4000.0]},
        "gn-load": {"x": [-0.5, -0.005, 0.0, 0.005, 0.5], "y": [-2500.0, -1500.0, 0.0, 1500.0, 2500.0]},
        "gn-unload": {"x": [-0.01, 0.0, 0.01], "y": [-3000.0, 0.0, 3000.0]},
        "pulse": {"x": [0.0, 0.01, 0.03], "y": [0.0, 1.0, 0.0]},
        "pull": {"x": [0.0, 0.2], "y": [-1.0, -1.0]},
    },
    "nodes": {
        "ground": {"position": [0.0], "fixed": True},
        "a": {"position": [0.5], "mass": 4.0},
        "b": {"position": [1.0], "mass": 3.0},
        "c": {"position": [1.5], "mass": 2.0},
        "driver": {"position": [2.0], "mass": 1.0},
    },
    "springs": {
        "crush": {
            "nodes": ["ground", "a"],
            "material": {"type": "crush", "loading": "plateau", "unloading_stiffness": 2.0e6},
        },
        "link": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 2.0e5}},
        "dash": {"nodes": ["a", "b"], "material": {"type": "damper", "damping": 150.0}},
        "rubber": {"nodes": ["b", "c"], "material": {"type": "nonlinear_elastic", "curve": "soft"}},
        "yielding": {
            "nodes": ["c", "driver"],
            "material": {
                "type": "general_nonlinear",
                "loading": "gn-load",
                "unloading": "gn-unload",
                "tension_yield": 1500.0,
                "compression_yield": -1500.0,
            },
        },
    },
    "initial_velocity": {"a": [-6.0], "b": [-6.0], "c": [-6.0], "driver": [-2.0]},
    "gravity": [-G],
    "loads": [{"node": "b", "force": [-800.0], "curve": "pulse"}],
    "prescribed_motion": [
        {"node": "driver", "quantity": "velocity", "direction": "x", "curve": "pull", "scale": 2.0}
    ],
    "rigid_walls": [{"id": "stop", "point": [0.47], "normal": [1.0], "nodes": ["a"]}],
    "end_time": 0.06,
    "output": {"interval": 5.0e-4},
}

TWIN_2D_HELI: dict[str, Any] = {  # helicopter-like, 2 general_nonlinear, sliding onto a floor, gravity, load
    "name": "twin-2d-heli",
    "curves": {
        "uf-load": {
            "x": [-0.5, -0.223, -0.045, -0.009, 0.0, 10.0],
            "y": [-76000.0, -57200.0, -70000.0, -40000.0, 0.0, 5000.0],
        },
        "uf-unload": {"x": [-0.009, 0.0, 0.009], "y": [-40000.0, 0.0, 40000.0]},
        "cab-load": {"x": [-0.3, -0.27, -0.225, -0.01, 0.0], "y": [-1.0e6, -5.0e5, -1.5e5, -1.5e5, 0.0]},
        "cab-unload": {"x": [-0.006, 0.0, 0.006], "y": [-1.7e5, 0.0, 1.7e5]},
        "gust": {"x": [0.0, 0.02, 0.04], "y": [0.0, 1.0, 0.0]},
    },
    "nodes": {
        "ground": {"position": [0.0, 0.0], "fixed": True},
        "transmission": {"position": [0.02, 0.3], "mass": 100.0},
        "cabin": {"position": [0.0, 0.9], "mass": 300.0},
    },
    "springs": {
        "underfloor": {
            "nodes": ["ground", "transmission"],
            "material": {
                "type": "general_nonlinear",
                "loading": "uf-load",
                "unloading": "uf-unload",
                "tension_yield": 5000.0,
                "compression_yield": -40000.0,
            },
        },
        "cabin": {
            "nodes": ["transmission", "cabin"],
            "material": {
                "type": "general_nonlinear",
                "loading": "cab-load",
                "unloading": "cab-unload",
                "compression_yield": -150000.0,
            },
        },
    },
    "initial_velocity": {"transmission": [0.5, -8.2], "cabin": [0.0, -8.2]},
    "gravity": [0.0, -G],
    "loads": [{"node": "cabin", "force": [2000.0, -5000.0], "curve": "gust"}],
    "rigid_walls": [{"id": "floor", "point": [0.0, 0.1], "normal": [0.0, 1.0], "nodes": ["transmission"]}],
    "end_time": 0.12,
    "output": {"interval": 1.0e-3},
}

TWIN_2D_MIXED: dict[
    str, Any
] = {  # crush, damper, linear, nonlinear; displacement + acceleration pm; inclined wall
    "name": "twin-2d-mixed",
    "curves": {
        "crumple": {"x": [-1.0, -0.05, -0.005, 0.0], "y": [-9000.0, -4000.0, -5000.0, 0.0]},
        "bushing": {"x": [-0.02, 0.0, 0.02], "y": [-3000.0, 0.0, 1500.0]},
        "push": {"x": [0.0, 0.05, 0.1], "y": [0.0, -0.03, -0.02]},
        "shake": {"x": [0.0, 0.02, 0.04, 0.1], "y": [0.0, 50.0, -50.0, 0.0]},
    },
    "nodes": {
        "base": {"position": [0.0, 0.0], "fixed": True},
        "ram": {"position": [0.0, 0.4], "mass": 2.0, "fixed": ["x"]},
        "bob": {"position": [0.3, 0.5], "mass": 1.5},
        "tip": {"position": [0.6, 0.3], "mass": 1.0},
        "shaker": {"position": [0.6, 0.0], "mass": 0.5},
    },
    "springs": {
        "crumple": {
            "nodes": ["base", "bob"],
            "material": {"type": "crush", "loading": "crumple", "unloading_stiffness": 4.0e5},
        },
        "dash": {"nodes": ["ram", "bob"], "material": {"type": "damper", "damping": 40.0}},
        "strut": {"nodes": ["ram", "bob"], "material": {"type": "linear_elastic", "stiffness": 5.0e4}},
        "bushing": {"nodes": ["bob", "tip"], "material": {"type": "nonlinear_elastic", "curve": "bushing"}},
        "arm": {"nodes": ["tip", "shaker"], "material": {"type": "linear_elastic", "stiffness": 2.0e4}},
    },
    "initial_velocity": {"bob": [-2.0, -3.0], "tip": [1.0, -1.0]},
    "gravity": [0.0, -G],
    "prescribed_motion": [
        {"node": "ram", "quantity": "displacement", "direction": "y", "curve": "push", "scale": 1.0},
        {"node": "shaker", "quantity": "acceleration", "direction": "x", "curve": "shake", "scale": 1.0},
    ],
    "rigid_walls": [{"id": "slope", "point": [0.6, 0.297], "normal": [-0.3, 1.0], "nodes": ["tip"]}],
    "end_time": 0.1,
    "output": {"interval": 1.0e-3},
}

TWINS = {
    "1d-all-materials": (TWIN_1D, "nodes.a.mass", [1.0, 2.0, 4.0, 6.0, 8.0]),
    "2d-helicopter-wall": (TWIN_2D_HELI, "nodes.cabin.mass", [200.0, 250.0, 300.0, 350.0, 400.0]),
    "2d-mixed-prescribed": (TWIN_2D_MIXED, "nodes.bob.mass", [0.5, 1.0, 1.5, 2.0, 3.0]),
}


# --------------------------------------------------------------------------------------------------
# knot crossings (tests/test_knot_peaks.py)
# --------------------------------------------------------------------------------------------------

# A curve whose |force| has a local maximum of 1500 N at the knot x = -0.01 m (and, mirrored, at +0.01):
# from there the force falls to 1000 N (crush) or 500 N (elastic, general) over the next 0.09 m.
PEAK_Y = 1500.0  # N
MASS = 10.0  # kg
CURVES = {
    "crush": {"x": [-1.0, -0.1, -0.01, 0.0], "y": [-2000.0, -1000.0, -PEAK_Y, 0.0]},
    "elastic": {"x": [-0.1, -0.01, 0.0, 0.01, 0.1], "y": [-500.0, -PEAK_Y, 0.0, PEAK_Y, 500.0]},
    "steep": {"x": [-0.01, 0.0, 0.01], "y": [-1.0e5, 0.0, 1.0e5]},
}
MATERIALS = {
    "crush": {"type": "crush", "loading": "crush", "unloading_stiffness": 1.0e6},
    "nonlinear_elastic": {"type": "nonlinear_elastic", "curve": "elastic"},
    # yields at -1000 N on the first segment, then crushes on over the knot (mode -1 loading path)
    "general_nonlinear": {
        "type": "general_nonlinear",
        "loading": "elastic",
        "unloading": "steep",
        "compression_yield": -1000.0,
    },
}


def one_mass(kind: str, dim: int = 1, dt: float = 2.5e-4) -> dict[str, Any]:
    """A 10 kg mass at 1 m from a fixed node, moving toward it at 4 m/s on one spring of ``kind``.

    The spring passes over the 1500 N knot while loading (at ~2.5 ms), turns at -0.064 / -0.073 m below
    1300 N,
    and (crush) separates. ``dim`` 2 puts the spring on the diagonal (0.6, 0.8). Fixed ``dt``; histories at
    every step.
    """
    pos, vel = ([1.0], [-4.0]) if dim == 1 else ([0.6, 0.8], [-2.4, -3.2])
    return {
        "name": f"knot-{kind}-{dim}d",
        "curves": CURVES,
        "nodes": {
            "ground": {"position": [0.0] * dim, "fixed": True},
            "body": {"position": pos, "mass": MASS},
        },
        "springs": {"s": {"nodes": ["ground", "body"], "material": MATERIALS[kind]}},
        "initial_velocity": {"body": vel},
        "end_time": 0.06,
        "time_step": {"dt": dt},
        "output": {"interval": dt, "histories": ["spring_force", "spring_elongation"]},
    }


FRONT_X = [-0.9, -0.7, -0.05, -0.01, 0.0]  # m
FRONT_Y = [-2.0e6, -3.5e5, -2.5e5, -3.2e5, 0.0]  # N
M_B, M_O, K_BELT, K_U, V0, T_END = 1200.0, 80.0, 1.5e5, 4.0e7, 15.0, 0.15
CRUSH_REBOUND: dict[str, Any] = {
    "name": "crush-rebound",
    "curves": {"front": {"x": FRONT_X, "y": FRONT_Y}},
    "nodes": {
        "barrier": {"position": [0.0], "fixed": True},
        "body": {"position": [0.8], "mass": M_B},
        "occupant": {"position": [1.6], "mass": M_O},
    },
    "springs": {
        "front": {
            "nodes": ["barrier", "body"],
            "material": {"type": "crush", "loading": "front", "unloading_stiffness": K_U},
        },
        "belt": {"nodes": ["body", "occupant"], "material": {"type": "linear_elastic", "stiffness": K_BELT}},
    },
    "initial_velocity": {"body": [-V0], "occupant": [-V0]},
    "end_time": T_END,
    "output": {"interval": T_END, "histories": "none"},
}

# --------------------------------------------------------------------------------------------------
# features of the generated kernel (tests/test_generated.py) and of both fast kernels
# --------------------------------------------------------------------------------------------------


def without_walls_and_loads(
    model: dict[str, Any], keep_gravity: bool = True, keep_walls: bool = False
) -> dict[str, Any]:
    """``model`` without what generated kernels leave to the generic one (prescribed motion), and without
    its walls and loads / gravity unless kept."""
    m = copy.deepcopy(model)
    for key in (
        ("prescribed_motion",)
        + (() if keep_walls else ("rigid_walls", "loads"))
        + (() if keep_gravity else ("gravity",))
    ):
        m.pop(key, None)
    for node in m["nodes"].values():  # a prescribed dof of the twin becomes a free one
        node.pop("fixed", None) if node.get("fixed") is not True else None
    m["output"]["histories"] = "all"
    return m


def one_d_materials(mirror: bool = False, gravity: bool = False) -> dict[str, Any]:
    """TWIN_1D without loads and prescribed motion: crush, linear + damper in parallel, nonlinear elastic,
    general_nonlinear; ``gravity`` keeps its gravity, its rigid wall and its load pulse. ``mirror`` draws
    the model right to left (every spring's 1-D sign is -1)."""
    m = without_walls_and_loads(TWIN_1D, keep_gravity=gravity, keep_walls=gravity)
    if mirror:
        for node in m["nodes"].values():
            node["position"] = [-node["position"][0]]
        m["initial_velocity"] = {k: [-v[0]] for k, v in m["initial_velocity"].items()}
    return m


def mount_reversal() -> dict[str, Any]:
    """A 170 kg engine driven at 3 m/s into an engine mount (general_nonlinear, yield +-20 kN): it yields
    in compression, unloads along the 4.5e6 N/m line and the spring-back (about 100 J stored against
    44 J needed) carries it past the tension yield: general_nonlinear rule 4 (the reversal path) runs."""
    return {
        "name": "mount-reversal",
        "curves": {
            "load": {
                "x": [-0.1, -0.04, -0.01, 0.0, 0.01, 0.04, 0.1],
                "y": [-3.0e5, -3.0e4, -2.0e4, 0.0, 2.0e4, 3.0e4, 3.0e5],
            },
            "unload": {"x": [-0.01, 0.0, 0.01], "y": [-4.5e4, 0.0, 4.5e4]},
        },
        "nodes": {"frame": {"position": [0.0], "fixed": True}, "engine": {"position": [0.2], "mass": 170.0}},
        "springs": {
            "mount": {
                "nodes": ["frame", "engine"],
                "material": {
                    "type": "general_nonlinear",
                    "loading": "load",
                    "unloading": "unload",
                    "tension_yield": 2.0e4,
                    "compression_yield": -2.0e4,
                },
            }
        },
        "initial_velocity": {"engine": [-3.0]},
        "end_time": 0.08,
        "output": {"interval": 2.0e-4, "histories": ["spring_force", "spring_elongation", "acceleration"]},
    }


def crush_bounce(v0: float = 10.0) -> dict[str, Any]:
    """A 100 kg mass at v0 onto a crush spring with a 20 kN plateau (reached after 0.1 mm) and unloading
    stiffness 2e6 N/m, then free flight: crush for m v0 / F0, spring-back for a quarter period of
    sqrt(k_u / m), then the spring is separated and opening."""
    return {
        "name": "crush-bounce",
        "curves": {"plateau": {"x": [-2.0, -1.0e-4, 0.0], "y": [-2.0e4, -2.0e4, 0.0]}},
        "nodes": {"wall": {"position": [0.0], "fixed": True}, "body": {"position": [1.0], "mass": 100.0}},
        "springs": {
            "pad": {
                "nodes": ["wall", "body"],
                "material": {"type": "crush", "loading": "plateau", "unloading_stiffness": 2.0e6},
            }
        },
        "initial_velocity": {"body": [-v0]},
        "end_time": 0.2,
        "time_step": {"tolerance": 1.0e-5},
        "termination": {"kinetic_energy_fraction": 1.0e-3},
        "output": {"interval": 1.0e-3, "histories": ["spring_force"]},
    }


# --------------------------------------------------------------------------------------------------
# the twin cases: several disjoint sub-systems share one model (one generated kernel compile) wherever
# their features can live together; each sub-system keeps its own check (tests/test_kernel_twins.py)
# --------------------------------------------------------------------------------------------------

_CURVE_KEYS = ("loading", "unloading", "curve")


def disjoint(parts: dict[str, dict[str, Any]], base: dict[str, Any] | None = None) -> dict[str, Any]:
    """One model of the sub-systems ``parts`` (prefix -> model without gravity, or with the base's), side by side and
    unconnected: every node, spring, wall and used curve ``id`` becomes ``<prefix>-<id>`` (a part's walls
    hold its own nodes, its loads and prescribed motion act on them); end time, time step and output are
    the first part's. With ``base``, the parts are added beside that model (kept as it is: its ids, walls,
    loads, gravity, prescribed motion, end time, step and output)."""
    first = next(iter(parts.values()))
    model: dict[str, Any] = copy.deepcopy(base) if base else {"name": "-".join(parts)}
    for key in ("curves", "nodes", "springs", "initial_velocity"):
        model.setdefault(key, {})
    for p, part in parts.items():
        assert part.get("gravity", model.get("gravity")) == model.get("gravity"), p  # the base's, if any

        def curve(cid: str, p: str = p, part: dict[str, Any] = part) -> str:
            model["curves"][f"{p}-{cid}"] = part["curves"][cid]
            return f"{p}-{cid}"

        for sid, sp in part["springs"].items() if "springs" in part else ():
            sp = copy.deepcopy(sp)
            sp["nodes"] = [f"{p}-{n}" for n in sp["nodes"]]
            mat = sp["material"]
            for key in _CURVE_KEYS:
                if key in mat:
                    mat[key] = curve(mat[key])
            for rc in mat.get("curves", []):
                rc["curve"] = curve(rc["curve"])
            model["springs"][f"{p}-{sid}"] = sp
        model["nodes"].update({f"{p}-{n}": copy.deepcopy(v) for n, v in part["nodes"].items()})
        model["initial_velocity"].update({f"{p}-{n}": v for n, v in part.get("initial_velocity", {}).items()})
        for wall in part.get("rigid_walls", []):
            wall = copy.deepcopy(wall)
            wall["id"], wall["nodes"] = f"{p}-{wall['id']}", [f"{p}-{n}" for n in wall["nodes"]]
            model.setdefault("rigid_walls", []).append(wall)
        for key in ("loads", "prescribed_motion"):
            for item in part.get(key, []):
                item = dict(item, node=f"{p}-{item['node']}")
                if "curve" in item:
                    item["curve"] = curve(item["curve"])
                model.setdefault(key, []).append(item)
    if base is None:
        model.update({k: copy.deepcopy(first[k]) for k in ("end_time", "time_step", "output") if k in first})
    return model


def part_of(out: KernelOutput, plan: Any, prefix: str) -> KernelOutput:
    """The output of sub-system ``prefix`` of a :func:`disjoint` model, as if it had run alone: its nodes,
    springs and walls in their order (per-variant numbers, e.g. ``status``, are the whole model's)."""
    topo = plan.topology

    def own(ids: Any) -> list[int]:
        return [k for k, i in enumerate(ids) if i.startswith(prefix + "-")]

    take = {"node": own(topo.node_ids), "spring": own(topo.spring_ids), "wall": own(topo.wall_ids)}
    per = {"peak_acceleration": "node", "peak_wall_force": "wall", "wall_impulse": "wall"}
    per |= {f: "spring" for f in ("peak_force", "max_crush", "absorbed_energy", "max_elongation")}
    per |= {"spring_fail_time": "spring"}
    part = copy.copy(out)
    for name, dim in per.items():
        setattr(part, name, getattr(out, name)[take[dim]])
    part.histories = {}
    for name, h in out.histories.items():
        for axis, dim in enumerate(ALL_SHAPES[name], start=1):
            h = np.take(h, take[dim], axis=axis) if dim in take else h
        part.histories[name] = h
    return part


def full_twin_both_ways() -> dict[str, Any]:
    """TWIN_1D (every material left to right, walls, gravity, load, prescribed velocity) with
    :func:`one_d_materials` drawn right to left beside it (``rev-``, under the same gravity), to 0.03 s
    instead of TWIN_1D's 0.06 (the reference run 1.5 s of CPU instead of 4.0): by then the crush springs
    have reached their plateau and unloaded, the general_nonlinear ones yielded and unloaded."""
    model = disjoint({"rev": one_d_materials(True)}, base=TWIN_1D)
    model["end_time"] = 0.03
    return model


def knots(dim: int, scaled: bool = False) -> dict[str, Any]:
    """:func:`one_mass` of every curve material side by side (``crush-``, ``elastic-``, ``general-``);
    ``scaled`` adds them a second time (``s-crush-`` ...), for the curves that :data:`SCALED_KNOTS` scales."""
    parts = {p: one_mass(k, dim=dim, dt=4e-4) for k, p in _KNOT_PREFIX.items()}
    return disjoint(parts | ({f"s-{p}": part for p, part in parts.items()} if scaled else {}))


def _v2_parts(dim: int) -> dict[str, dict[str, Any]]:
    """The SPEC v2 spring features breaking (``f-``) beside rate_elastic (``r-``); in 1-D, intact (``i-``)
    too. (2-D has no ``i-``: a spring's 2-D code and its breaking code are separate, each checked here: 2-D
    in ``f-``, intact in 1-D ``i-``; in 2-D the springs without a failure option, ``f-nd``, ``f-gn`` and
    ``r-``, still run beside breaking ones.)"""
    return (
        {"f": _v2_springs(dim)}
        | ({"i": _v2_intact(dim)} if dim == 1 else {})
        | {"r": rate_elastic_model(dim)}
    )


def springs_1d() -> dict[str, Any]:
    """:func:`knots` 1-D on constant and on scaled curves (``k-``), :data:`CRUSH_REBOUND` (``cr-``),
    :func:`mount_reversal` (``mount-``) and :func:`_v2_parts` 1-D side by side, on the knots' fixed step of
    0.4 ms, to 0.08 s (the mount's reversal ends after 0.06 s; the v2 springs that break do by then)."""
    parts = {"k": knots(1, scaled=True), "cr": CRUSH_REBOUND, "mount": mount_reversal(), **_v2_parts(1)}
    model = disjoint(parts)
    model["end_time"] = 0.08
    return model


def springs_2d() -> dict[str, Any]:
    """:func:`_v2_parts` 2-D (its step, end time 0.3 s and output) with :func:`one_mass` 2-D of every curve
    material beside them (``crush-``, ``elastic-``, ``general-``), to 0.1 s (the v2 springs that break do
    by then; the reference run 0.9 s of CPU instead of 2.3 at 0.3 s)."""
    model = disjoint(_v2_parts(2) | {p: one_mass(k, dim=2) for k, p in _KNOT_PREFIX.items()})
    model["end_time"] = 0.1
    return model


_KNOT_PREFIX = {"crush": "crush", "nonlinear_elastic": "elastic", "general_nonlinear": "general"}
KNOT_MASSES = {f"nodes.{p}-body.mass": MASSES for p in _KNOT_PREFIX.values()}
# force and abscissa scales of every spring curve of :func:`knots` ``scaled`` but the unloading one
# (per-variant factors)
SCALED_KNOTS = {
    f"curves.s-{c}.{f}": v
    for c in ("crush-crush", "elastic-elastic", "general-elastic")
    for f, v in (("scale", [0.7, 0.8, 0.9, 1.0, 0.75]), ("x_scale", [1.0, 1.1, 1.2, 1.3, 1.4]))
}


def _helicopter_walls() -> dict[str, Any]:
    model = without_walls_and_loads(TWIN_2D_HELI, keep_walls=True)
    model["rigid_walls"][0]["nodes"] = ["transmission", "cabin"]  # the floor
    model["rigid_walls"].append(
        {"id": "side", "point": [0.03, 0.0], "normal": [-1.0, 0.0], "nodes": ["transmission", "cabin"]}
    )
    return model


def _helicopter_penalty_side() -> dict[str, Any]:
    """:func:`_helicopter_walls` with a penalty side wall (contact stiffness a study axis)."""
    model = _helicopter_walls()
    model["rigid_walls"][1]["stiffness"] = 1.0e6
    return model


def full_twin_2d() -> dict[str, Any]:
    """TWIN_2D_MIXED (crush, damper, linear, nonlinear; prescribed displacement and acceleration, an
    inclined rigid wall ``slope``), with :func:`_helicopter_penalty_side` beside it (``h-``: two
    general_nonlinear springs, its load pulse, a rigid floor and a penalty side wall holding both masses),
    under the same gravity, to 0.06 s (TWIN_2D_MIXED's 0.1 s: the reference run 8.6 s of CPU instead of
    4.2; by 0.06 s every wall is hit and the helicopter's underfloor has passed its largest crush)."""
    model = disjoint({"h": _helicopter_penalty_side()}, base=TWIN_2D_MIXED)
    model["end_time"] = 0.06
    return model


def _bounce_many() -> dict[str, Any]:
    """:func:`crush_bounce` to 0.3 s on a step tolerance of 1e-3 (6900 steps at most instead of 67800 at
    1e-5: the reference run, twice per test session, 1.3 s of CPU instead of 12): every variant of the
    early-termination case still stops before 0.2 s, each at its own time."""
    model = crush_bounce()
    model["end_time"] = 0.3
    model["time_step"] = {"tolerance": 1.0e-3}
    return model


# the knots' masses and curve scales, and the mount's speeds (one more than the 4 of its own case: 2.75)
KNOTS_AND_REVERSAL = {
    **{k.replace("nodes.", "nodes.k-"): v for k, v in KNOT_MASSES.items()},
    **{k.replace("curves.", "curves.k-"): v for k, v in SCALED_KNOTS.items()},
    "nodes.cr-body.mass": [900.0, 1100.0, 1200.0, 1300.0, 1500.0],
    "initial_velocity.mount-engine.0": [-2.0, -2.5, -2.75, -3.0, -3.5],
}

# force and abscissa scales of spring, time and motion curves (a constant shape and per-variant factors)
_SCALED_1D = {
    "curves.plateau.scale": [0.6, 0.7, 0.8, 0.9, 1.0],
    "curves.soft.x_scale": [1.0, 1.1, 1.2, 1.3, 1.4],
    "curves.gn-load.scale": [1.0, 0.9, 0.8, 0.7, 0.95],
    "curves.pulse.x_scale": [0.5, 0.8, 1.0, 1.5, 2.0],
    "curves.pull.x_scale": [1.0, 0.5, 2.0, 1.5, 0.8],
}


def _v2_springs(dim: int) -> dict[str, Any]:
    """The SPEC v2 spring features together: elastoplastic (preloaded, breaking in tension), a blow-off
    nonlinear_damper, a preloaded general_nonlinear that yielded on the way, a preloaded crush, a linear
    spring breaking both ways."""
    ax = [1.0] if dim == 1 else [0.6, 0.8]
    at = lambda r: [r * c for c in ax]  # noqa: E731
    return {
        "name": f"v2-springs-{dim}d",
        "curves": {
            "blow-off": {"x": [-10.0, -1.0, 0.0, 1.0, 10.0], "y": [-300.0, -300.0, 0.0, 300.0, 300.0]},
            "load": {"x": [-0.1, 0.0, 0.01, 0.02, 0.2], "y": [-1.0e4, 0.0, 600.0, 400.0, 900.0]},
            "unload": {"x": [-0.1, 0.0, 0.1], "y": [-1.0e4, 0.0, 1.0e4]},
            "crush": {"x": [-0.3, -0.01, 0.0], "y": [-3000.0, -1500.0, 0.0]},
        },
        "nodes": {
            "a": {"position": at(0.0), "fixed": True},
            "b": {"position": at(1.0), "mass": 10.0},
            "c": {"position": at(2.0), "mass": 5.0},
        },
        "springs": {
            "ep": {
                "nodes": ["a", "b"],
                "initial_elongation": 0.02,
                "failure": {"tension": 0.12},
                "material": {
                    "type": "elastoplastic",
                    "stiffness": 4.0e4,
                    "tangent_stiffness": 1.0e4,
                    "yield_force": 2.0e3,
                },
            },
            "nd": {"nodes": ["a", "b"], "material": {"type": "nonlinear_damper", "curve": "blow-off"}},
            "gn": {
                "nodes": ["b", "c"],
                "initial_elongation": 0.015,
                "material": {
                    "type": "general_nonlinear",
                    "loading": "load",
                    "unloading": "unload",
                    "tension_yield": 500.0,
                },
            },
            "cr": {
                "nodes": ["b", "c"],
                "initial_elongation": -0.01,
                "failure": {"compression": -0.2},
                "material": {"type": "crush", "loading": "crush", "unloading_stiffness": 2.0e5},
            },
            "lin": {
                "nodes": ["a", "c"],
                "failure": {"tension": 0.06, "compression": -0.06},
                "material": {"type": "linear_elastic", "stiffness": 2.0e3},
            },
        },
        "initial_velocity": {"b": at(3.0), "c": at(-2.0)},
        "end_time": 0.3,
        "time_step": {"safety_factor": 0.5},
        "output": {"interval": 1.0e-3},
    }


def _v2_intact(dim: int) -> dict[str, Any]:
    """:func:`_v2_springs` without failures and without its general_nonlinear spring (never breaking, it is
    the same code as :func:`_v2_springs`' one): springs that cannot break beside ones that can."""
    model = _v2_springs(dim)
    model["springs"].pop("gn")
    for sp in model["springs"].values():
        sp.pop("failure", None)
    return model


def rate_elastic_model(dim: int) -> dict[str, Any]:
    """rate_elastic: three curves (rates 0, 2, 6 m/s) on a preloaded spring, one curve on another, beside a
    linear spring; the impact speeds put the elongation rates below, between and above the rates, and a
    curve scale axis makes one of its curves a per-variant factor curve."""
    ax = [1.0] if dim == 1 else [0.6, 0.8]
    at = lambda r: [r * c for c in ax]  # noqa: E731
    return {
        "name": f"rate-elastic-{dim}d",
        "curves": {
            "soft": {"x": [-0.2, -0.05, 0.0, 0.05, 0.2], "y": [-800.0, -500.0, 0.0, 500.0, 800.0]},
            "mid": {"x": [-0.2, -0.05, 0.0, 0.05, 0.2], "y": [-1600.0, -1000.0, 0.0, 1000.0, 1600.0]},
            "stiff": {"x": [-0.2, 0.0, 0.1, 0.2], "y": [-4000.0, 0.0, 1500.0, 2500.0]},
        },
        "nodes": {
            "a": {"position": at(0.0), "fixed": True},
            "b": {"position": at(1.0), "mass": 10.0},
            "c": {"position": at(2.0), "mass": 5.0},
        },
        "springs": {
            "re": {
                "nodes": ["a", "b"],
                "initial_elongation": 0.01,
                "material": {
                    "type": "rate_elastic",
                    "curves": [
                        {"rate": 0.0, "curve": "soft"},
                        {"rate": 2.0, "curve": "mid"},
                        {"rate": 6.0, "curve": "stiff"},
                    ],
                },
            },
            "re1": {
                "nodes": ["b", "c"],
                "material": {"type": "rate_elastic", "curves": [{"rate": 1.0, "curve": "mid"}]},
            },
            "lin": {"nodes": ["a", "c"], "material": {"type": "linear_elastic", "stiffness": 2.0e3}},
        },
        "initial_velocity": {"b": at(3.0), "c": at(-2.0)},
        "end_time": 0.3,
        "time_step": {"safety_factor": 0.5},
        "output": {"interval": 1.0e-3},
    }


_SPEEDS = [0.5, 2.0, 4.0, 6.0, 9.0]  # m/s


def _v2_axes(dim: int) -> dict[str, list[float]]:
    """The v2 parts' speeds (b and c at +-speed along their axis, as ``impact_velocity`` would set them, but
    only them: not the knots' bodies nor the mount) and a per-variant factor on a rate_elastic curve."""
    ax = [1.0] if dim == 1 else [0.6, 0.8]
    return {
        **{
            f"initial_velocity.{p}-{n}.{d}": [sg * c * v for v in _SPEEDS]
            for p in ("fir" if dim == 1 else "fr")
            for n, sg in (("b", 1.0), ("c", -1.0))
            for d, c in enumerate(ax)
        },
        "curves.r-mid.scale": [1.0, 0.8, 1.2, 1.0, 1.5],
    }


# the knots' masses up to 10 kg (as in :func:`one_mass`): at 14 kg the nonlinear elastic spring, run to 0.3 s
# on this model's 0.5 ms step, passes its curve's last knot (-0.1 m) and crushes to zero length
_SPRINGS_2D_AXES = _v2_axes(2) | {k: [6.0, 7.0, 8.0, 9.0, 10.0] for k in KNOT_MASSES}
# the general_nonlinear knot spring (``general-s``) of :func:`springs_2d` crushed to zero length in the last
# two variants (a heavy body at 12 and 16 m/s), the other variants as in its own case
CRUSHED_2D_AXES = _SPRINGS_2D_AXES | {
    "nodes.general-body.mass": [6.0, 7.0, 8.0, 5000.0, 5000.0],
    "initial_velocity.general-body.0": [-2.4, -2.4, -2.4, -7.2, -9.6],
    "initial_velocity.general-body.1": [-3.2, -3.2, -3.2, -9.6, -12.8],
}

# case -> (model builder, study axes); tests/test_kernel_twins.py CHECKS says what each case must exercise
CASES: dict[str, tuple[Callable[[], dict[str, Any]], dict[str, list[float]]]] = {
    "full-twin-1d-every-material-both-ways-scaled-curves": (
        full_twin_both_ways,
        {
            "nodes.a.mass": TWINS["1d-all-materials"][2],
            "nodes.rev-a.mass": [8.0, 6.0, 4.0, 2.0, 1.0],
            **_SCALED_1D,
        },
    ),
    "full-twin-2d-mixed-prescribed-helicopter-rigid-and-penalty-walls": (
        full_twin_2d,
        {
            "nodes.bob.mass": TWINS["2d-mixed-prescribed"][2],
            "nodes.h-cabin.mass": [200.0, 250, 300, 350, 400],
            "rigid_walls.2.stiffness": [2e5, 5e5, 1e6, 2e6, 4e6],
        },
    ),
    "2d-v2-spring-features-rate-elastic-and-knots": (springs_2d, _SPRINGS_2D_AXES),
    "2d-crushed-to-zero": (springs_2d, CRUSHED_2D_AXES),  # the shape of the case above: no compile of its own
    "1d-knots-constant-and-scaled-crush-rebound-reversal-v2-spring-features-and-rate-elastic": (
        springs_1d,
        KNOTS_AND_REVERSAL | _v2_axes(1),
    ),
    # 40 variants of 13 different steps ending each at its own time (lane compaction)
    "early-termination": (
        _bounce_many,
        {
            "impact_velocity": list(np.linspace(4.0, 16.0, 40)),
            "nodes.body.mass": list(np.random.default_rng(3).permutation(np.linspace(60.0, 140.0, 40))),
        },
    ),
}

# cases run with the per-step record of every movable node (tests/test_metrics.py's record twins are these
# shapes: one compile serves both files); the others run without a record
RECORD_CASES = (
    "full-twin-1d-every-material-both-ways-scaled-curves",
    "full-twin-2d-mixed-prescribed-helicopter-rigid-and-penalty-walls",
    "2d-v2-spring-features-rate-elastic-and-knots",
    "2d-crushed-to-zero",
    "early-termination",
)
# a slow compile, started at session start on the other core beside helpers.generated_part's shape and the
# crash criteria (~46 CPU s in all): about as long as the generic kernel alone (~51 s) (tests/conftest.py)
WARM_RECORD_CASES = ("full-twin-2d-mixed-prescribed-helicopter-rigid-and-penalty-walls",)


def record_case(case: str) -> tuple[Any, Any, tuple[int, ...]]:
    """(batch, plan, record) of a twin case, ``record`` every movable node when the case is one of
    ``RECORD_CASES``, else ()."""
    build, axes = CASES[case]
    batch, plan = model_batch(build(), axes)
    topo = plan.topology
    record = tuple(n for n in range(topo.n_nodes) if not topo.fixed[n].all() or n in batch.pm_node)
    return batch, plan, record if case in RECORD_CASES else ()
