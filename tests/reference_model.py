"""The scipy reference solver's model: tabulated curves, loads and the equations of motion
(:class:`_Model`). Part of the independent scipy reference solver (reference_scipy.py, which
describes its scope, physics and numerics); like it, it does not import ``crashstudy``."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

_AXES = ("x", "y")


# --------------------------------------------------------------------------------------------------
# Curves
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Curve:
    """A tabulated curve ``y(x)`` (x strictly increasing, at least two points).

    Attributes
    ----------
    x, y : numpy.ndarray
        Abscissae (displacement [L] for material curves, time [T] for load curves) and ordinates
        (force [F] for material curves, a dimensionless scale for load curves).
    """

    x: np.ndarray
    y: np.ndarray
    lo_slope: float = field(init=False)
    hi_slope: float = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "lo_slope", float((self.y[1] - self.y[0]) / (self.x[1] - self.x[0])))
        object.__setattr__(self, "hi_slope", float((self.y[-1] - self.y[-2]) / (self.x[-1] - self.x[-2])))

    def extrapolated(self, e: np.ndarray) -> np.ndarray:
        """Material-curve value: linear interpolation, linear extrapolation along the end segments.

        Parameters
        ----------
        e : numpy.ndarray
            Elongation [L].

        Returns
        -------
        numpy.ndarray
            Force [F], same shape as ``e``.
        """
        x, y = self.x, self.y
        e = np.asarray(e, dtype=float)
        out = np.interp(e, x, y)
        below, above = e < x[0], e > x[-1]
        if below.any():
            out = np.where(below, y[0] + (e - x[0]) * self.lo_slope, out)
        if above.any():
            out = np.where(above, y[-1] + (e - x[-1]) * self.hi_slope, out)
        return out

    def antiderivative(self, e: np.ndarray) -> np.ndarray:
        """``int_0^e C(xi) dxi`` of the extrapolated curve (exact: the curve is piecewise linear).

        Parameters
        ----------
        e : numpy.ndarray
            Elongation [L].

        Returns
        -------
        numpy.ndarray
            Strain energy [E] stored by a ``nonlinear_elastic`` spring at elongation ``e``.
        """
        return self._from_first_knot(np.asarray(e, dtype=float)) - self._from_first_knot(np.zeros(1))[0]

    def _from_first_knot(self, e: np.ndarray) -> np.ndarray:
        x, y = self.x, self.y
        cum = np.concatenate(([0.0], np.cumsum(0.5 * np.diff(x) * (y[1:] + y[:-1]))))
        k = np.clip(np.searchsorted(x, e, side="right") - 1, 0, x.size - 1)
        # Trapezoid from knot k to e is exact for a linear piece; for e < x[0] (k = 0) and e > x[-1]
        # (k = last) the piece is the extrapolated first/last segment.
        return cum[k] + 0.5 * (e - x[k]) * (y[k] + self.extrapolated(e))

    def in_time(self, t: np.ndarray) -> np.ndarray:
        """Load-curve value: linear interpolation inside ``[x[0], x[-1]]``, zero outside.

        Parameters
        ----------
        t : numpy.ndarray
            Time [T].

        Returns
        -------
        numpy.ndarray
            Load scale [-], same shape as ``t``.
        """
        t = np.asarray(t, dtype=float)
        inside = (t >= self.x[0]) & (t <= self.x[-1])
        return np.where(inside, np.interp(t, self.x, self.y), 0.0)


def _parse_curve(cid: str, raw: Any) -> _Curve:
    if not isinstance(raw, Mapping) or "x" not in raw or "y" not in raw:
        raise ValueError(f"curves.{cid}: expected a mapping with 'x' and 'y' lists")
    x = np.asarray(raw["x"], dtype=float) * float(raw.get("x_scale", 1.0))
    y = np.asarray(raw["y"], dtype=float) * float(raw.get("scale", 1.0))
    if x.ndim != 1 or x.shape != y.shape or x.size < 2:
        raise ValueError(f"curves.{cid}: 'x' and 'y' must be equal-length lists of >= 2 numbers")
    if not np.all(np.diff(x) > 0.0):
        raise ValueError(f"curves.{cid}: 'x' must be strictly increasing")
    return _Curve(x=x, y=y)


# --------------------------------------------------------------------------------------------------
# Compiled model
# --------------------------------------------------------------------------------------------------


@dataclass
class _Load:
    node: int
    force: np.ndarray  # (D,) [F]
    curve: _Curve | None


@dataclass
class _Model:
    """Arrays of a parsed model; ``N`` nodes, ``S`` springs, ``D`` = 1 or 2 dimensions."""

    node_ids: tuple[str, ...]
    spring_ids: tuple[str, ...]
    dim: int
    x0: np.ndarray  # (N, D) initial positions [L]
    mass: np.ndarray  # (N,) [M]; 0 for a massless node fixed in every direction
    free: np.ndarray  # (N, D) bool
    inv_mass: np.ndarray  # (N, D) 1/m on free dofs, 0 on fixed dofs [1/M]
    v0: np.ndarray  # (N, D) [L/T]
    gravity: np.ndarray  # (D,) [L/T^2]
    ni: np.ndarray  # (S,) int
    nj: np.ndarray  # (S,) int
    d0: np.ndarray  # (S, D) X_j - X_i [L]
    l0: np.ndarray  # (S,) initial length [L]
    sign: np.ndarray  # (S,) s = sign(X_j - X_i), used in 1-D
    incidence: np.ndarray  # (N, S): +1 at node i, -1 at node j
    materials: tuple[str, ...]
    lin_idx: np.ndarray
    lin_k: np.ndarray
    damp_idx: np.ndarray
    damp_c: np.ndarray
    curve_springs: tuple[tuple[int, _Curve], ...]
    loads: tuple[_Load, ...]
    end_time: float

    @property
    def n_dof(self) -> int:
        return self.x0.size

    # ---- mechanics, batched over a leading time axis --------------------------------------------

    def kinematics(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Elongation, elongation rate and force direction of every spring.

        Parameters
        ----------
        u, v : numpy.ndarray
            Displacements [L] and velocities [L/T], shape ``(T, N, D)``.

        Returns
        -------
        e : numpy.ndarray
            Elongation [L], ``(T, S)``.
        edot : numpy.ndarray
            Elongation rate [L/T], ``(T, S)``.
        n : numpy.ndarray
            Unit vector from node i to node j, ``(T, S, D)``; in 1-D ``s`` as ``(1, S, 1)``.
        """
        du = u[:, self.nj] - u[:, self.ni]
        dv = v[:, self.nj] - v[:, self.ni]
        if self.dim == 1:
            n = self.sign[None, :, None]
            e = self.sign * du[..., 0]
        else:
            d = self.d0 + du
            length = np.sqrt(np.sum(d * d, axis=-1))
            if np.any(length <= 1e-12 * self.l0):
                bad = self.spring_ids[int(np.argmin(np.min(length / self.l0, axis=0)))]
                raise FloatingPointError(f"spring {bad!r} crushed to zero length")
            n = d / length[..., None]
            # L - L0 without cancellation: (L^2 - L0^2) / (L + L0).
            e = (2.0 * np.sum(self.d0 * du, axis=-1) + np.sum(du * du, axis=-1)) / (length + self.l0)
        edot = np.sum(n * dv, axis=-1)
        return e, edot, n

    def spring_forces(self, e: np.ndarray, edot: np.ndarray) -> np.ndarray:
        """Force [F] of every spring (positive = tension), ``(T, S)``."""
        f = np.zeros_like(e)
        if self.lin_idx.size:
            f[:, self.lin_idx] = self.lin_k * e[:, self.lin_idx]
        if self.damp_idx.size:
            f[:, self.damp_idx] = self.damp_c * edot[:, self.damp_idx]
        for s, curve in self.curve_springs:
            f[:, s] = curve.extrapolated(e[:, s])
        return f

    def strain_energy(self, e: np.ndarray) -> np.ndarray:
        """Elastic energy [E] stored in every spring, ``(T, S)`` (0 for dampers)."""
        w = np.zeros_like(e)
        if self.lin_idx.size:
            w[:, self.lin_idx] = 0.5 * self.lin_k * e[:, self.lin_idx] ** 2
        for s, curve in self.curve_springs:
            w[:, s] = curve.antiderivative(e[:, s])
        return w

    def external_forces(self, t: np.ndarray, segment_mid: float | None = None) -> np.ndarray:
        """Gravity plus concentrated loads [F] on every node, ``(T, N, D)``.

        Parameters
        ----------
        t : numpy.ndarray
            Times [T], ``(T,)``.
        segment_mid : float, optional
            When integrating one piece between load breakpoints, its mid time: a curve's on/off state
            is then taken from the piece (the one-sided limit at the piece's ends), not from ``t``.
        """
        f = np.empty((t.size, *self.x0.shape))
        f[:] = self.mass[:, None] * self.gravity
        for load in self.loads:
            if load.curve is None:
                scale = np.ones_like(t)
            elif segment_mid is None:
                scale = load.curve.in_time(t)
            else:
                on = load.curve.x[0] <= segment_mid <= load.curve.x[-1]
                scale = np.interp(t, load.curve.x, load.curve.y) if on else np.zeros_like(t)
            f[:, load.node] += scale[:, None] * load.force
        return f

    def evaluate(
        self, t: np.ndarray, u: np.ndarray, v: np.ndarray, segment_mid: float | None = None
    ) -> dict[str, np.ndarray]:
        """Everything derived from a batch of states.

        Returns
        -------
        dict
            ``e``, ``edot``, ``force`` ``(T, S)``; ``acceleration`` ``(T, N, D)`` [L/T^2];
            ``ext_power`` ``(T,)`` [E/T] (gravity and loads); ``spring_power`` ``(T, S)`` [E/T]
            (work rate done on each spring, ``F de/dt``).
        """
        e, edot, n = self.kinematics(u, v)
        force = self.spring_forces(e, edot)
        f_ext = self.external_forces(t, segment_mid)
        f_nodes = self.incidence @ (force[..., None] * n) + f_ext
        acc = f_nodes * self.inv_mass
        ext_power = np.sum(f_ext * v * self.free, axis=(1, 2))
        return {
            "e": e,
            "edot": edot,
            "force": force,
            "acceleration": acc,
            "ext_power": ext_power,
            "spring_power": force * edot,
        }

    def rhs_for(self, segment_mid: float) -> Callable[[float, np.ndarray], np.ndarray]:
        """The ``solve_ivp`` right-hand side for one piece between load breakpoints."""
        nd = self.n_dof
        shape = (1, *self.x0.shape)

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            u = y[:nd].reshape(shape)
            v = y[nd : 2 * nd].reshape(shape)
            out = self.evaluate(np.array([t]), u, v, segment_mid)
            return np.concatenate(
                (y[nd : 2 * nd], out["acceleration"].ravel(), out["ext_power"], out["spring_power"][0])
            )

        return rhs
