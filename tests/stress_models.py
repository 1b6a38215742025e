"""Model builders of the stability stress suite (tests/test_stress.py), shared with tests/test_wall_passive.py
and benchmarks/stress.py (its table runs the same models): chains, stiffness and mass ratios, snap-through,
the conservative two-mass model, dampers, the frontal and helicopter models, and a batch with one variant's
step forced above its critical step by hand."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scipy.linalg import eigvalsh_tridiagonal

from crashstudy.arrays.batch import build_batch
from crashstudy.arrays.compiler import apply_axis
from crashstudy.schema.yamlio import load_yaml
from helpers import STUDIES, model_plan

FRONTAL = STUDIES / "models" / "frontal-9mass.yaml"
HELICOPTER = STUDIES / "models" / "helicopter-subfloor.yaml"


def critical(model: dict[str, Any]) -> tuple[float, str, str]:
    """(dt_crit, controlling node id, controlling spring id) of a one-variant model."""
    plan = model_plan(model)
    topo = plan.topology
    _, steps = build_batch(topo, plan.base[:, None], plan.interval)
    n, s = int(steps.control_node[0]), int(steps.control_spring[0])
    return float(steps.dt_crit[0]), topo.node_ids[n] if n >= 0 else "", topo.spring_ids[s] if s >= 0 else ""


def at_step(model: dict[str, Any], steps: int, samples: int = 1) -> dict[str, Any]:
    """The model run for ``steps`` steps of (almost exactly) its ``safety_factor`` step.

    The output interval is a whole number of steps (x (1 - 1e-12), so that the solver's snapping of the
    step to the interval keeps it just below the requested one), and ``end_time`` is ``steps`` of them.
    """
    dt_crit, _, _ = critical(model)
    sf = model.get("time_step", {}).get("safety_factor", 1.0)
    per = max(1, steps // samples)
    interval = per * sf * dt_crit * (1.0 - 1e-12)
    return dict(model, end_time=samples * interval, output=dict(model.get("output", {}), interval=interval))


def chain(n: int, unequal: bool, fixed: bool, safety_factor: float = 1.0) -> dict[str, Any]:
    """1-D chain of ``n`` masses on linear springs, every mass started at a random velocity (all modes,
    the highest included, are excited); ``fixed``: an extra fixed node at one end, else both ends free.
    Unequal: masses log-uniform in [0.01, 100] kg, stiffnesses log-uniform in [1e3, 1e5] N/m; equal:
    1 kg and 1e4 N/m.
    """
    rng = np.random.default_rng(1000 * n + 2 * unequal + fixed)
    mass = 10.0 ** rng.uniform(-2, 2, n) if unequal else np.ones(n)
    nodes: dict[str, Any] = {"ground": {"position": [0.0], "fixed": True}} if fixed else {}
    nodes.update({f"m{i}": {"position": [float(i + 1)], "mass": float(mass[i])} for i in range(n)})
    ids = list(nodes)
    k = 10.0 ** rng.uniform(3, 5, len(ids) - 1) if unequal else np.full(len(ids) - 1, 1.0e4)
    springs = {
        f"s{i}": {
            "nodes": [ids[i], ids[i + 1]],
            "material": {"type": "linear_elastic", "stiffness": float(k[i])},
        }
        for i in range(len(ids) - 1)
    }
    v0 = rng.uniform(-1.0, 1.0, n)
    return {
        "name": f"chain-{n}",
        "nodes": nodes,
        "springs": springs,
        "initial_velocity": {f"m{i}": [float(v0[i])] for i in range(n)},
        "end_time": 1.0,
        "time_step": {"safety_factor": safety_factor},
        "output": {"histories": "none"},
    }


def chain_omega_max(model: dict[str, Any]) -> float:
    """Largest natural circular frequency of a linear chain built by :func:`chain` (dense eigensolver)."""
    ids = [k for k, v in model["nodes"].items() if not v.get("fixed")]
    idx = {k: i for i, k in enumerate(ids)}
    n = len(ids)
    K = np.zeros((n, n))
    for s in model["springs"].values():
        k = s["material"]["stiffness"]
        a, b = (idx.get(q) for q in s["nodes"])
        for p, q in ((a, a), (b, b)):
            if p is not None:
                K[p, q] += k
        if a is not None and b is not None:
            K[a, b] -= k
            K[b, a] -= k
    M = np.array([model["nodes"][i]["mass"] for i in ids])
    Ms = 1.0 / np.sqrt(M)
    A = Ms[:, None] * K * Ms[None, :]  # tridiagonal: nodes are numbered along the chain
    lam = eigvalsh_tridiagonal(
        np.diag(A).copy(), np.diag(A, 1).copy(), select="i", select_range=(n - 1, n - 1)
    )
    return float(np.sqrt(lam[0]))


def ratio_model(k_ratio: float, m_ratio: float, safety_factor: float = 1.0) -> dict[str, Any]:
    """ground --soft (1 N/m)-- heavy (1 kg) --stiff (k_ratio N/m)-- light (1/m_ratio kg), both started at 1 m/s."""
    return {
        "name": "ratios",
        "nodes": {
            "ground": {"position": [0.0], "fixed": True},
            "heavy": {"position": [1.0], "mass": 1.0},
            "light": {"position": [2.0], "mass": 1.0 / m_ratio},
        },
        "springs": {
            "soft": {"nodes": ["ground", "heavy"], "material": {"type": "linear_elastic", "stiffness": 1.0}},
            "stiff": {
                "nodes": ["heavy", "light"],
                "material": {"type": "linear_elastic", "stiffness": k_ratio},
            },
        },
        "initial_velocity": {"heavy": [1.0], "light": [1.0]},
        "end_time": 1.0,
        "time_step": {"safety_factor": safety_factor},
        "output": {"histories": ["displacement"]},
    }


def ratio_closed_form(k_ratio: float, m_ratio: float, t: np.ndarray) -> np.ndarray:
    """Exact displacement (T, 2) of heavy and light in :func:`ratio_model`: two modes, written so that
    the slow mode is not lost to cancellation (the stable root of the characteristic quadratic)."""
    k, K, M, m = 1.0, k_ratio, 1.0, 1.0 / m_ratio
    a, b, c = M * m, M * K + m * (k + K), k * K
    disc = math.sqrt(b * b - 4 * a * c)
    w2 = np.array([2 * c / (b + disc), (b + disc) / (2 * a)])  # slow, fast
    # mode shapes (heavy, light): from the light node's row, light / heavy = K / (K - m w^2)
    phi = np.stack([np.ones(2), K / (K - m * w2)])  # (2 dofs, 2 modes)
    Mm = np.array([M, m])
    v0 = np.ones(2)
    q = (phi.T @ (Mm * v0)) / np.einsum("im,i,im->m", phi, Mm, phi) / np.sqrt(w2)
    return np.sin(np.outer(t, np.sqrt(w2))) * q @ phi.T


def ratio_steps(k_ratio: float, m_ratio: float) -> int:
    """Steps of :func:`ratio_model` for a quarter of the slow period (the heavy mass's largest excursion)."""
    dt_crit, _, _ = critical(ratio_model(k_ratio, m_ratio))
    w_slow = math.sqrt(1.0 / (1.0 + 1.0 / m_ratio))
    return int(math.ceil(0.5 * math.pi / w_slow / dt_crit))


def snap_through(
    v0: float, time_step: dict[str, float] | None = None, end_time: float = 20.0
) -> dict[str, Any]:
    """A softening nonlinear_elastic spring (a buckling shell that keeps its sign, as every material curve
    must): compression resists up to 2 N at -0.5 m, softens at -4 N/m (the steepest slope, negative) to
    0 N at -1.0 m, and stiffens again at 4 N/m beyond. 1 kg moving at -v0. (Until 2026-11-26 this curve
    pulled back with 1 N at -1.0 m, a bistable shell; a force against the elongation is now refused.)"""
    model: dict[str, Any] = {
        "name": "snap-through",
        "curves": {"shell": {"x": [-1.5, -1.0, -0.5, 0.0, 1.0], "y": [-2.0, 0.0, -2.0, 0.0, 4.0]}},
        "nodes": {"anchor": {"position": [0.0], "fixed": True}, "body": {"position": [1.0], "mass": 1.0}},
        "springs": {
            "shell": {
                "nodes": ["anchor", "body"],
                "material": {"type": "nonlinear_elastic", "curve": "shell"},
            }
        },
        "initial_velocity": {"body": [-v0]},
        "end_time": end_time,
        "output": {"interval": end_time / 10, "histories": "none"},
    }
    if time_step:
        model["time_step"] = time_step
    return model


def snap_through_closed_form(v0: float) -> tuple[float, float, float]:
    """(max crush, max elongation, peak |force|) of :func:`snap_through` from energy conservation.

    Strain energy of a crush d: U = 2 d^2 up to d = 0.5 (U = 0.5), U = 4 d - 2 d^2 - 1 on the softening
    part up to d = 1 (U = 1), U = 1 + 2 (d - 1)^2 beyond; in tension U = 2 e^2.
    """
    E = 0.5 * v0 * v0
    elong = math.sqrt(E / 2.0)
    if E <= 0.5:
        crush = math.sqrt(E / 2.0)
        squeeze = 4.0 * crush
    elif E <= 1.0:  # on the softening part: 2 d^2 - 4 d + (1 + E) = 0
        crush = 1.0 - math.sqrt(2.0 * (1.0 - E)) / 2.0
        squeeze = 2.0  # the knot at -0.5 m
    else:
        crush = 1.0 + math.sqrt((E - 1.0) / 2.0)
        squeeze = max(2.0, 4.0 * (crush - 1.0))
    return crush, elong, max(4.0 * elong, squeeze)


def conservative(steps: int, safety_factor: float = 1.0) -> dict[str, Any]:
    """ground -- 1e4 N/m -- a (1 kg) -- 3e4 N/m -- b (2 kg), a at 1 m/s and b at -2 m/s; histories none."""
    model = {
        "name": "conservative",
        "nodes": {
            "ground": {"position": [0.0], "fixed": True},
            "a": {"position": [1.0], "mass": 1.0},
            "b": {"position": [2.0], "mass": 2.0},
        },
        "springs": {
            "s1": {"nodes": ["ground", "a"], "material": {"type": "linear_elastic", "stiffness": 1.0e4}},
            "s2": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 3.0e4}},
        },
        "initial_velocity": {"a": [1.0], "b": [-2.0]},
        "end_time": 1.0,
        "time_step": {"safety_factor": safety_factor},
        "output": {"histories": "none"},
    }
    return at_step(model, steps)


def damper_pair(safety_factor: float, stiffness: float | None = None) -> dict[str, Any]:
    """Two free 1 kg masses joined by a 1000 N s/m damper (and a parallel spring), b started at 1 m/s."""
    springs: dict[str, Any] = {"d": {"nodes": ["a", "b"], "material": {"type": "damper", "damping": 1000.0}}}
    if stiffness:
        springs["s"] = {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": stiffness}}
    model = {
        "name": "damper-pair",
        "nodes": {"a": {"position": [0.0], "mass": 1.0}, "b": {"position": [1.0], "mass": 1.0}},
        "springs": springs,
        "initial_velocity": {"b": [1.0]},
        "end_time": 1.0,
        "time_step": {"safety_factor": safety_factor},
        "output": {"histories": "none"},
    }
    return at_step(model, 200)


def frontal(time_step: dict[str, float] | None = None) -> dict[str, Any]:
    """frontal-9mass with histories off; ``time_step`` replaces the model's (default tolerance 1e-3)."""
    model = load_yaml(str(FRONTAL)).data  # YAML 1.2 numbers (1.0e6)
    model["output"] = dict(model["output"], histories="none")
    if time_step:
        model["time_step"] = time_step
        model["output"]["interval"] = model["end_time"] / 10  # coarse: the step is not cut by the sampling
    return model


def helicopter_study(tmp: Path, speeds: list[float], time_step: dict[str, float] | None = None) -> Path:
    """A study file over impact_velocity on the 2-D helicopter sub-floor model."""
    study: dict[str, Any] = {
        "name": "heli-speeds",
        "model": str(HELICOPTER),
        "matrix": {"impact_velocity": speeds},
    }
    if time_step:
        study["set"] = {"time_step": time_step}
    path = tmp / "heli-speeds.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path


def mass_axis_study(tmp: Path, dt: float, masses: list[float]) -> Path:
    """A study over the mass of the free end of a 2-mass chain run at a fixed ``dt``."""
    model = {
        "name": "fixed-dt-chain",
        "nodes": {
            "ground": {"position": [0.0], "fixed": True},
            "a": {"position": [1.0], "mass": 1.0},
            "b": {"position": [2.0], "mass": 1.0},
        },
        "springs": {
            "s1": {"nodes": ["ground", "a"], "material": {"type": "linear_elastic", "stiffness": 1.0e4}},
            "s2": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 1.0e4}},
        },
        "initial_velocity": {"a": [1.0], "b": [1.0]},
        "end_time": 0.5,
        "time_step": {"dt": dt},
        "output": {"interval": 0.01, "histories": "none"},
    }
    (tmp / "chain.yaml").write_text(yaml.safe_dump(model, sort_keys=False))
    study = {"name": "light-ends", "model": "chain.yaml", "matrix": {"nodes.b.mass": masses}}
    path = tmp / "light-ends.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path


def forced_batch(
    scale: float,
    n_variants: int = 4,
    bad: int = 1,
    model: dict[str, Any] | None = None,
    samples: int = 1,
    n_steps: int = 2000,
):
    """A batch of ``conservative``-like variants (different speeds) with variant ``bad``'s dt set to
    ``scale`` x its dt_crit by hand, ``n_steps`` steps of the others, every history kept at ``samples``
    intervals (:func:`at_step`); ``model`` instead of ``conservative`` when given. Returns (batch, steps,
    plan)."""
    model = at_step(conservative(1) if model is None else model, n_steps, samples)
    model["output"] = {"interval": model["output"]["interval"], "histories": "all"}
    plan = model_plan(model)
    topo = plan.topology
    P = np.repeat(plan.base[:, None], n_variants, axis=1)
    apply_axis(P, topo.paths["impact_velocity"], np.linspace(1.0, 2.0, n_variants))
    batch, steps = build_batch(topo, P, plan.interval)
    batch.dt[bad] = scale * steps.dt_crit[bad]
    return batch, steps, plan
