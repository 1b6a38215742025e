"""The scipy baseline's model: a model dict (docs/format.md; no prescribed motion, no walls) read into
small arrays: curves, springs, the branch state of the history-dependent springs.

Part of the scipy baseline of the benchmarks (scipy_models.py, which describes it)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

_AXES = ("x", "y")


@dataclass
class Curve:
    x: np.ndarray
    y: np.ndarray

    def __post_init__(self) -> None:
        self.s0 = float((self.y[1] - self.y[0]) / (self.x[1] - self.x[0]))
        self.s1 = float((self.y[-1] - self.y[-2]) / (self.x[-1] - self.x[-2]))
        self.xl, self.yl = list(map(float, self.x)), list(map(float, self.y))

    def __call__(self, e: Any) -> Any:
        """Linear interpolation, linear extrapolation along the end segments (material curves)."""
        if np.ndim(e) == 0:
            e = float(e)
            if e <= self.xl[0]:
                return self.yl[0] + self.s0 * (e - self.xl[0])
            if e >= self.xl[-1]:
                return self.yl[-1] + self.s1 * (e - self.xl[-1])
            return float(np.interp(e, self.x, self.y))
        out = np.interp(e, self.x, self.y)
        out = np.where(e < self.x[0], self.y[0] + self.s0 * (e - self.x[0]), out)
        return np.where(e > self.x[-1], self.y[-1] + self.s1 * (e - self.x[-1]), out)

    def in_time(self, t: Any) -> Any:
        """Time curve: interpolated inside its range, zero outside."""
        inside = (t >= self.x[0]) & (t <= self.x[-1])
        return np.where(inside, np.interp(t, self.x, self.y), 0.0)

    def inverse(self, f: float, direction: float) -> float:
        """Elongation where the curve reaches ``f``, searched from the origin outward (as the kernel's
        ``curve_inverse``)."""
        prev_x, prev_y = 0.0, float(self(0.0))
        xs = self.xl if direction > 0 else self.xl[::-1]
        ys = self.yl if direction > 0 else self.yl[::-1]
        for xk, yk in zip(xs, ys, strict=True):
            if xk * direction > 0:
                lo, hi = min(prev_y, yk), max(prev_y, yk)
                if hi > lo and lo <= f <= hi:
                    return prev_x + (f - prev_y) / (yk - prev_y) * (xk - prev_x)
                prev_x, prev_y = xk, yk
        slope = self.s1 if direction > 0 else self.s0
        if slope != 0.0 and (f - prev_y) / slope * direction >= 0:
            return prev_x + (f - prev_y) / slope
        return prev_x


@dataclass
class Spring:
    kind: str
    i: int
    j: int
    k: float = 0.0  # stiffness / damping / unloading stiffness
    L: Curve | None = None  # curve / loading curve
    U: Curve | None = None  # unloading curve (general_nonlinear)
    yt: float = math.inf
    yc: float = -math.inf


@dataclass
class Branch:
    """The branch of a history-dependent spring (docs/format.md, in continuous time)."""

    mode: int = 0  # crush: -1 crushing, 0 not; general_nonlinear: 0 elastic, +1 / -1 yielded direction
    loading: bool = True  # general_nonlinear, mode != 0: on the (shifted) loading curve, else unloading
    emin: float = 0.0  # crush e_min
    fstar: float = 0.0  # crush F*
    et: float = 0.0
    ft: float = 0.0
    ec: float = 0.0
    fc: float = 0.0
    shift: float = 0.0
    yld_t: bool = False
    yld_c: bool = False


@dataclass
class Model:
    dim: int
    x0: np.ndarray  # (N, D)
    mass: np.ndarray
    free: np.ndarray  # (N, D) float
    inv_mass: np.ndarray  # (N, D)
    v0: np.ndarray
    gravity: np.ndarray
    springs: list[Spring]
    ni: np.ndarray
    nj: np.ndarray
    d0: np.ndarray  # (S, D)
    l0: np.ndarray
    sign: np.ndarray
    incidence: np.ndarray  # (N, S)
    loads: list[tuple[int, np.ndarray, Curve | None]]
    end_time: float
    node_ids: tuple[str, ...]
    spring_ids: tuple[str, ...]
    hyst: list[int] = field(default_factory=list)  # indices of crush / general_nonlinear springs

    @property
    def nd(self) -> int:
        return self.x0.size


def compile_model(m: dict[str, Any]) -> Model:
    """A model dict (as the YAML file loads) -> arrays. No prescribed motion, no walls."""
    if m.get("prescribed_motion") or m.get("rigid_walls"):
        raise NotImplementedError("prescribed_motion / rigid_walls")
    curves = {}
    for cid, raw in (m.get("curves") or {}).items():
        x = np.asarray(raw["x"], float) * float(raw.get("x_scale", 1.0))
        curves[cid] = Curve(x, np.asarray(raw["y"], float) * float(raw.get("scale", 1.0)))
    nodes = m["nodes"]
    node_ids = tuple(nodes)
    index = {n: k for k, n in enumerate(node_ids)}
    x0 = np.array([np.atleast_1d(np.asarray(nodes[n]["position"], float)) for n in node_ids])
    N, D = x0.shape
    free = np.ones((N, D))
    mass = np.zeros(N)
    for k, n in enumerate(node_ids):
        fx = nodes[n].get("fixed")
        if fx is True:
            free[k] = 0.0
        elif fx:
            for a in [fx] if isinstance(fx, str) else fx:
                free[k, _AXES.index(str(a))] = 0.0
        mass[k] = float(nodes[n].get("mass") or 0.0)
    inv_mass = np.where(free > 0, 1.0 / np.where(mass > 0, mass, 1.0)[:, None], 0.0)
    v0 = np.zeros((N, D))
    for n, vel in (m.get("initial_velocity") or {}).items():
        v0[index[n]] = np.asarray(vel, float)
    gravity = np.asarray(m.get("gravity") or [0.0] * D, float)
    springs, spring_ids = [], tuple(m["springs"])
    for sid in spring_ids:
        raw = m["springs"][sid]
        i, j = index[raw["nodes"][0]], index[raw["nodes"][1]]
        mat = raw["material"]
        t = mat["type"]
        if t == "linear_elastic":
            springs.append(Spring(t, i, j, k=float(mat["stiffness"])))
        elif t == "damper":
            springs.append(Spring(t, i, j, k=float(mat["damping"])))
        elif t == "nonlinear_elastic":
            springs.append(Spring(t, i, j, L=curves[mat["curve"]]))
        elif t == "crush":
            springs.append(Spring(t, i, j, k=float(mat["unloading_stiffness"]), L=curves[mat["loading"]]))
        elif t == "general_nonlinear":
            springs.append(
                Spring(
                    t,
                    i,
                    j,
                    L=curves[mat["loading"]],
                    U=curves[mat["unloading"]],
                    yt=float(mat.get("tension_yield", math.inf)),
                    yc=float(mat.get("compression_yield", -math.inf)),
                )
            )
        else:
            raise NotImplementedError(t)
    ni = np.array([s.i for s in springs])
    nj = np.array([s.j for s in springs])
    d0 = x0[nj] - x0[ni]
    S = len(springs)
    inc = np.zeros((N, S))
    inc[ni, np.arange(S)] += 1.0
    inc[nj, np.arange(S)] -= 1.0
    loads = [
        (index[ld["node"]], np.asarray(ld["force"], float), curves[ld["curve"]] if ld.get("curve") else None)
        for ld in (m.get("loads") or [])
    ]
    return Model(
        D,
        x0,
        mass,
        free,
        inv_mass,
        v0,
        gravity,
        springs,
        ni,
        nj,
        d0,
        np.sqrt((d0 * d0).sum(-1)),
        np.sign(d0[:, 0]) if D == 1 else np.ones(S),
        inc,
        loads,
        float(m["end_time"]),
        node_ids,
        spring_ids,
        [k for k, s in enumerate(springs) if s.kind in ("crush", "general_nonlinear")],
    )
