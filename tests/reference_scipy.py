"""Independent reference solver for crashstudy models, built on :func:`scipy.integrate.solve_ivp`.

This module is the *independent truth* the test suite and the benchmarks compare the explicit
central-difference solver against. It deliberately does not import ``crashstudy``: it reads the
plain dict a model file loads to (docs/format.md) and integrates the equations of motion with a
high-order adaptive Runge-Kutta method (DOP853 by default) at tight tolerances.

Scope
-----
Only the smooth material laws of docs/format.md are supported:

* ``linear_elastic``: ``F = k e``;
* ``nonlinear_elastic``: ``F = C(e)``, ``C`` interpolated linearly and extrapolated beyond its ends
  along the first/last segment;
* ``damper``: ``F = c de/dt``.

``general_nonlinear``, ``crush``, ``prescribed_motion`` and ``rigid_walls`` raise
:class:`NotImplementedError` (they are history dependent or non-smooth; an ODE reference would
need event handling to be trustworthy there).

Physics (docs/format.md, spring materials)
------------------------
Elongation ``e`` (negative = compression); positive ``F`` is tension and pulls the nodes together.

* 2-D: ``e = L - L0``; node ``i`` receives ``+F n`` and node ``j`` receives ``-F n`` with
  ``n = (x_j - x_i) / L``; ``de/dt = n . (v_j - v_i)``.
* 1-D: ``e = s (u_j - u_i)`` with ``s = sign(X_j - X_i)`` from the initial positions; node ``i``
  receives ``+s F``, node ``j`` receives ``-s F``; ``de/dt = s (v_j - v_i)``.

Fixed degrees of freedom keep zero velocity. Gravity acts on every mass. Load curves are functions of
time, zero outside their ``x`` range and linearly interpolated inside; a load without a curve is
constant. All numbers are in the model's one consistent unit system (``units`` is ignored), written
below as [L] length, [T] time, [M] mass, [F] force, [E] energy.

Numerics
--------
The state integrated is ``(u, v, W_ext, W_spring)``: nodal displacements and velocities plus, as
auxiliary quadratures, the external work of gravity and loads and the work done on every spring
(``int F de``), which give an energy balance independent of the material law. The time axis is cut
at every load-curve abscissa inside ``(0, end_time)`` and each piece is integrated separately, so a
load that starts, stops or bends is never stepped over; inside a piece the load is evaluated as the
one-sided continuation of its curve. Results are evaluated from the ``dense_output`` interpolants.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

__all__ = ["RefResult", "solve_reference", "SUPPORTED_MATERIALS", "UNSUPPORTED_MATERIALS"]

SUPPORTED_MATERIALS = ("linear_elastic", "nonlinear_elastic", "damper")
UNSUPPORTED_MATERIALS = ("general_nonlinear", "crush")
_UNSUPPORTED_KEYS = ("prescribed_motion", "rigid_walls")
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


def _parse_fixed(value: Any, dim: int, where: str) -> np.ndarray:
    mask = np.zeros(dim, dtype=bool)
    if value is None or value is False:
        return mask
    if value is True:
        return ~mask
    if isinstance(value, str):
        value = [value]
    if isinstance(value, Sequence):
        items = list(value)
        if items and all(isinstance(it, (bool, np.bool_)) for it in items):
            if len(items) != dim:
                raise ValueError(f"{where}.fixed: {len(items)} flags for a {dim}-D model")
            return np.array(items, dtype=bool)
        for it in items:
            name = str(it).strip().lower()
            if name not in _AXES[:dim]:
                raise ValueError(f"{where}.fixed: unknown axis {it!r} (expected {list(_AXES[:dim])})")
            mask[_AXES.index(name)] = True
        return mask
    raise ValueError(f"{where}.fixed: expected true/false or a list of axes, got {value!r}")


def _vector(value: Any, dim: int, where: str) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    if arr.shape != (dim,):
        raise ValueError(f"{where}: expected {dim} component(s), got {value!r}")
    return arr


def _compile(model: Mapping[str, Any]) -> _Model:
    for key in _UNSUPPORTED_KEYS:
        if model.get(key):
            raise NotImplementedError(f"reference_scipy does not support {key!r}")

    curves = {str(cid): _parse_curve(str(cid), raw) for cid, raw in (model.get("curves") or {}).items()}

    nodes_raw = model.get("nodes") or {}
    if not nodes_raw:
        raise ValueError("model has no nodes")
    node_ids = tuple(str(k) for k in nodes_raw)
    positions = [np.atleast_1d(np.asarray(nodes_raw[k]["position"], dtype=float)) for k in nodes_raw]
    dims = {p.size for p in positions}
    if len(dims) != 1 or dims.pop() not in (1, 2):
        raise ValueError("every node position must have the same number (1 or 2) of coordinates")
    dim = positions[0].size
    x0 = np.array(positions, dtype=float).reshape(len(node_ids), dim)
    index = {nid: k for k, nid in enumerate(node_ids)}

    mass = np.zeros(len(node_ids))
    free = np.ones((len(node_ids), dim), dtype=bool)
    for k, (nid, raw) in enumerate(nodes_raw.items()):
        free[k] = ~_parse_fixed(raw.get("fixed"), dim, f"nodes.{nid}")
        m = raw.get("mass")
        if free[k].any():
            if m is None or not float(m) > 0.0:
                raise ValueError(f"nodes.{nid}: a node that is not fixed in every direction needs mass > 0")
        mass[k] = float(m) if m is not None else 0.0
    inv_mass = np.zeros_like(x0)
    with np.errstate(divide="ignore"):
        inv_mass[free] = np.broadcast_to((1.0 / np.where(mass > 0, mass, 1.0))[:, None], x0.shape)[free]

    v0 = np.zeros_like(x0)
    for nid, vel in (model.get("initial_velocity") or {}).items():
        if str(nid) not in index:
            raise ValueError(f"initial_velocity: unknown node {nid!r}")
        k = index[str(nid)]
        v0[k] = _vector(vel, dim, f"initial_velocity.{nid}")
        if np.any(v0[k][~free[k]] != 0.0):
            raise ValueError(f"initial_velocity.{nid}: non-zero velocity along a fixed direction")

    gravity = np.zeros(dim)
    if model.get("gravity") is not None:
        gravity = _vector(model["gravity"], dim, "gravity")

    springs_raw = model.get("springs") or {}
    spring_ids = tuple(str(k) for k in springs_raw)
    ni = np.zeros(len(spring_ids), dtype=int)
    nj = np.zeros(len(spring_ids), dtype=int)
    materials: list[str] = []
    lin_idx: list[int] = []
    lin_k: list[float] = []
    damp_idx: list[int] = []
    damp_c: list[float] = []
    curve_springs: list[tuple[int, _Curve]] = []
    for s, (sid, raw) in enumerate(springs_raw.items()):
        pair = list(raw["nodes"])
        if len(pair) != 2 or pair[0] == pair[1] or any(str(p) not in index for p in pair):
            raise ValueError(f"springs.{sid}.nodes: expected two different known nodes, got {pair!r}")
        ni[s], nj[s] = index[str(pair[0])], index[str(pair[1])]
        mat = raw["material"]
        kind = str(mat["type"])
        materials.append(kind)
        if kind == "linear_elastic":
            lin_idx.append(s)
            lin_k.append(float(mat["stiffness"]))
        elif kind == "nonlinear_elastic":
            cid = str(mat["curve"])
            if cid not in curves:
                raise ValueError(f"springs.{sid}.material.curve: unknown curve {cid!r}")
            curve_springs.append((s, curves[cid]))
        elif kind == "damper":
            damp_idx.append(s)
            damp_c.append(float(mat["damping"]))
        elif kind in UNSUPPORTED_MATERIALS:
            raise NotImplementedError(f"springs.{sid}: material {kind!r} is not supported by the reference")
        else:
            raise ValueError(f"springs.{sid}.material.type: unknown material {kind!r}")
    d0 = x0[nj] - x0[ni]
    l0 = np.sqrt(np.sum(d0 * d0, axis=-1))
    if np.any(l0 == 0.0):
        raise ValueError("every spring needs a non-zero initial length")
    sign = np.sign(d0[:, 0]) if dim == 1 else np.ones(len(spring_ids))
    incidence = np.zeros((len(node_ids), len(spring_ids)))
    incidence[ni, np.arange(len(spring_ids))] += 1.0
    incidence[nj, np.arange(len(spring_ids))] -= 1.0

    loads: list[_Load] = []
    for k, raw in enumerate(model.get("loads") or []):
        nid = str(raw["node"])
        if nid not in index:
            raise ValueError(f"loads[{k}].node: unknown node {nid!r}")
        curve = None
        if raw.get("curve") is not None:
            cid = str(raw["curve"])
            if cid not in curves:
                raise ValueError(f"loads[{k}].curve: unknown curve {cid!r}")
            curve = curves[cid]
        loads.append(
            _Load(node=index[nid], force=_vector(raw["force"], dim, f"loads[{k}].force"), curve=curve)
        )

    end_time = float(model["end_time"])
    if not end_time > 0.0:
        raise ValueError("end_time must be > 0")

    return _Model(
        node_ids=node_ids,
        spring_ids=spring_ids,
        dim=dim,
        x0=x0,
        mass=mass,
        free=free,
        inv_mass=inv_mass,
        v0=v0,
        gravity=gravity,
        ni=ni,
        nj=nj,
        d0=d0,
        l0=l0,
        sign=sign,
        incidence=incidence,
        materials=tuple(materials),
        lin_idx=np.array(lin_idx, dtype=int),
        lin_k=np.array(lin_k, dtype=float),
        damp_idx=np.array(damp_idx, dtype=int),
        damp_c=np.array(damp_c, dtype=float),
        curve_springs=tuple(curve_springs),
        loads=tuple(loads),
        end_time=end_time,
    )


# --------------------------------------------------------------------------------------------------
# Piecewise dense output
# --------------------------------------------------------------------------------------------------


@dataclass
class _PiecewiseDense:
    """``solve_ivp`` dense outputs of consecutive pieces ``[bounds[k], bounds[k+1]]``."""

    bounds: np.ndarray
    pieces: list[Any]

    def __call__(self, t: np.ndarray) -> np.ndarray:
        """State ``(T, n_state)`` at times ``t`` [T] inside ``[0, end_time]``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        lo, hi = self.bounds[0], self.bounds[-1]
        slack = 1e-12 * max(abs(hi), 1.0)
        if np.any(t < lo - slack) or np.any(t > hi + slack):
            raise ValueError(f"times must lie in [{lo}, {hi}]")
        t = np.clip(t, lo, hi)
        which = np.clip(np.searchsorted(self.bounds, t, side="right") - 1, 0, len(self.pieces) - 1)
        out = np.empty((t.size, self.pieces[0](self.bounds[0]).size))
        for k in np.unique(which):
            mask = which == k
            out[mask] = np.atleast_2d(self.pieces[k](t[mask]).T).reshape(int(mask.sum()), -1)
        return out


# --------------------------------------------------------------------------------------------------
# Result
# --------------------------------------------------------------------------------------------------


@dataclass
class RefResult:
    """Histories of a reference run on the requested times.

    Attributes
    ----------
    t : numpy.ndarray
        Times [T], ``(T,)``.
    position : numpy.ndarray
        Nodal positions [L], ``(T, N, D)``.
    velocity : numpy.ndarray
        Nodal velocities [L/T], ``(T, N, D)``.
    acceleration : numpy.ndarray
        Nodal accelerations [L/T^2], ``(T, N, D)`` (zero along fixed directions).
    spring_force : numpy.ndarray
        Spring forces [F], positive = tension, ``(T, S)``.
    spring_elongation : numpy.ndarray
        Spring elongations [L], negative = compression, ``(T, S)``.
    node_ids, spring_ids : tuple of str
        Ids in model order (the ``N`` and ``S`` axes).
    nfev : int
        Right-hand-side evaluations spent by ``solve_ivp`` over all pieces.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    spring_force: np.ndarray
    spring_elongation: np.ndarray
    node_ids: tuple[str, ...]
    spring_ids: tuple[str, ...]
    nfev: int
    _model: _Model = field(repr=False)
    _dense: _PiecewiseDense = field(repr=False)
    _cache: dict[Any, Any] = field(default_factory=dict, repr=False)

    # ---- convenience ------------------------------------------------------------------------------

    @property
    def end_time(self) -> float:
        """Model end time [T]."""
        return self._model.end_time

    @property
    def dim(self) -> int:
        """Number of coordinates per node (1 or 2)."""
        return self._model.dim

    @property
    def displacement(self) -> np.ndarray:
        """Nodal displacements [L], ``(T, N, D)``."""
        return self.position - self._model.x0

    def node_index(self, node_id: str) -> int:
        """Index of ``node_id`` along the node axis."""
        return self.node_ids.index(node_id)

    def spring_index(self, spring_id: str) -> int:
        """Index of ``spring_id`` along the spring axis."""
        return self.spring_ids.index(spring_id)

    def sample(self, t: np.ndarray | Sequence[float] | float) -> RefResult:
        """The same solution evaluated (from the dense output) at other times.

        Parameters
        ----------
        t : array_like
            Times [T] inside ``[0, end_time]``.

        Returns
        -------
        RefResult
            A result on ``t`` sharing this run's dense output.
        """
        return _make_result(self._model, self._dense, np.atleast_1d(np.asarray(t, dtype=float)), self.nfev)

    def _state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        y = self._dense(t)
        nd = self._model.n_dof
        shape = (y.shape[0], *self._model.x0.shape)
        return y[:, :nd].reshape(shape), y[:, nd : 2 * nd].reshape(shape), y[:, 2 * nd], y[:, 2 * nd + 1 :]

    # ---- energy -----------------------------------------------------------------------------------

    def energy(self, t: np.ndarray | Sequence[float] | float | None = None) -> np.ndarray:
        """Kinetic energy plus elastic energy stored in the springs.

        For ``nonlinear_elastic`` springs the stored energy is ``int_0^e C``; dampers store nothing.
        Gravity and loads are *not* included: the sum is conserved only for a model without
        dampers, gravity or loads (see :meth:`energy_balance` for the general check).

        Parameters
        ----------
        t : array_like, optional
            Times [T]; default: this result's ``t``.

        Returns
        -------
        numpy.ndarray
            Energy [E], one value per time.
        """
        parts = self.energy_balance(t)
        return parts["kinetic"] + parts["strain"]

    def energy_balance(self, t: np.ndarray | Sequence[float] | float | None = None) -> dict[str, np.ndarray]:
        """Energy bookkeeping in the terms of docs/format.md (results).

        Parameters
        ----------
        t : array_like, optional
            Times [T]; default: this result's ``t``.

        Returns
        -------
        dict of numpy.ndarray
            ``kinetic`` [E]; ``strain`` [E] (elastic energy stored, from the material law);
            ``internal_work`` [E] (work done on all springs and dampers, ``sum int F de``, integrated
            with the motion); ``external_work`` [E] (gravity and loads, integrated with the motion);
            ``error`` [E] ``= kinetic + internal_work - kinetic(0) - external_work`` (zero for the
            exact solution); ``relative_error`` [-] ``= |error| / max(kinetic(0) + |external_work|, tiny)``.
        """
        tt = self.t if t is None else np.atleast_1d(np.asarray(t, dtype=float))
        u, v, w_ext, w_spring = self._state(tt)
        mdl = self._model
        e, _, _ = mdl.kinematics(u, v)
        kinetic = 0.5 * np.sum(mdl.mass[:, None] * mdl.free * v * v, axis=(1, 2))
        ke0 = 0.5 * np.sum(mdl.mass[:, None] * mdl.free * mdl.v0 * mdl.v0)
        internal = np.sum(w_spring, axis=1)
        err = kinetic + internal - ke0 - w_ext
        denom = np.maximum(ke0 + np.abs(w_ext), np.finfo(float).tiny)
        return {
            "kinetic": kinetic,
            "strain": np.sum(mdl.strain_energy(e), axis=1),
            "internal_work": internal,
            "external_work": w_ext,
            "error": err,
            "relative_error": np.abs(err) / denom,
        }

    def absorbed_energy(self) -> dict[str, float]:
        """Work [E] done on each spring from 0 to ``end_time`` (``int F de``), by spring id."""
        _, _, _, w_spring = self._state(np.array([self.end_time]))
        return {sid: float(w_spring[0, s]) for s, sid in enumerate(self.spring_ids)}

    # ---- peaks ------------------------------------------------------------------------------------

    def dense_peaks(self, n: int = 20001, refine: bool = True) -> dict[str, dict[str, Any]]:
        """Peaks over ``[0, end_time]`` from the dense output.

        The solution is evaluated on ``n`` equally spaced times; with ``refine`` each maximum is then
        polished by a bounded scalar search on the dense output between the neighbouring grid points,
        so the peaks carry the integration accuracy rather than the grid's.

        Parameters
        ----------
        n : int
            Number of grid times (>= 3).
        refine : bool
            Polish every maximum with :func:`scipy.optimize.minimize_scalar` (bounded).

        Returns
        -------
        dict
            ``peak_force`` {spring id: max |F| [F]}; ``peak_acceleration`` {node id: max |a| [L/T^2]}
            (Euclidean magnitude; 0 for a fully fixed node); ``max_crush`` {spring id: max(-e) [L]}
            (>= 0 since ``e(0) = 0``); and ``time_of`` {"peak_force" | "peak_acceleration" |
            "max_crush": {id: time [T] of that maximum}}.
        """
        key = (int(n), bool(refine))
        if key in self._cache:
            return self._cache[key]
        if n < 3:
            raise ValueError("n must be >= 3")
        grid = np.linspace(0.0, self.end_time, int(n))
        mdl = self._model

        def quantities(tt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            u, v, _, _ = self._state(tt)
            out = mdl.evaluate(tt, u, v)
            acc = np.sqrt(np.sum(out["acceleration"] ** 2, axis=-1))
            return np.abs(out["force"]), acc, -out["e"]

        on_grid = quantities(grid)
        names = ("peak_force", "peak_acceleration", "max_crush")
        ids = (self.spring_ids, self.node_ids, self.spring_ids)
        result: dict[str, dict[str, Any]] = {name: {} for name in names}
        result["time_of"] = {name: {} for name in names}
        for q, (name, qids) in enumerate(zip(names, ids, strict=True)):
            values = on_grid[q]
            for c, cid in enumerate(qids):
                k = int(np.argmax(values[:, c]))
                best_t, best = float(grid[k]), float(values[k, c])
                if refine:
                    a, b = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]

                    def neg(tau: float, q: int = q, c: int = c) -> float:
                        return -float(quantities(np.array([tau]))[q][0, c])

                    opt = minimize_scalar(
                        neg,
                        bounds=(a, b),
                        method="bounded",
                        options={"xatol": 1e-14 * max(self.end_time, 1.0)},
                    )
                    if -opt.fun > best:
                        best_t, best = float(opt.x), float(-opt.fun)
                result[name][cid] = best
                result["time_of"][name][cid] = best_t
        self._cache[key] = result
        return result

    def peak_force(self, spring_id: str) -> float:
        """Max |F| [F] of ``spring_id`` over ``[0, end_time]`` (from :meth:`dense_peaks`)."""
        return float(self.dense_peaks()["peak_force"][spring_id])


def _make_result(mdl: _Model, dense: _PiecewiseDense, t: np.ndarray, nfev: int) -> RefResult:
    y = dense(t)
    nd = mdl.n_dof
    shape = (t.size, *mdl.x0.shape)
    u, v = y[:, :nd].reshape(shape), y[:, nd : 2 * nd].reshape(shape)
    out = mdl.evaluate(t, u, v)
    return RefResult(
        t=t,
        position=mdl.x0 + u,
        velocity=v,
        acceleration=out["acceleration"],
        spring_force=out["force"],
        spring_elongation=out["e"],
        node_ids=mdl.node_ids,
        spring_ids=mdl.spring_ids,
        nfev=nfev,
        _model=mdl,
        _dense=dense,
    )


# --------------------------------------------------------------------------------------------------
# Entry point
# --------------------------------------------------------------------------------------------------


def solve_reference(
    model: Mapping[str, Any],
    t_eval: np.ndarray | None = None,
    method: str = "DOP853",
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_step: float | None = None,
) -> RefResult:
    """Integrate a model with :func:`scipy.integrate.solve_ivp` as an independent reference.

    Parameters
    ----------
    model : mapping
        The plain dict of a model file as YAML loads it (docs/format.md). ``units`` is ignored (all
        numbers are in one consistent system); ``time_step`` and ``output`` are ignored.
    t_eval : numpy.ndarray, optional
        Output times [T] in ``[0, end_time]``; default: 1001 equally spaced times. Any other time can
        be evaluated later with :meth:`RefResult.sample` (the dense output is kept).
    method : str
        ``solve_ivp`` method; DOP853 (explicit 8th order) suits these non-stiff problems.
    rtol, atol : float
        ``solve_ivp`` tolerances (``atol`` in the model's units of length, velocity and energy).
    max_step : float, optional
        Largest step [T]; default unlimited (the integration is already cut at every load-curve knot).

    Returns
    -------
    RefResult
        Histories on ``t_eval`` plus access to the dense solution.

    Raises
    ------
    NotImplementedError
        For ``general_nonlinear`` or ``crush`` springs, ``prescribed_motion`` or ``rigid_walls``.
    ValueError
        For a malformed model.
    FloatingPointError
        When a 2-D spring is crushed to zero length.
    RuntimeError
        When ``solve_ivp`` fails.
    """
    mdl = _compile(model)
    end = mdl.end_time
    knots = {0.0, end}
    for load in mdl.loads:
        if load.curve is not None:
            knots.update(float(x) for x in load.curve.x if 0.0 < x < end)
    bounds = np.array(sorted(knots))

    y = np.concatenate((np.zeros(mdl.n_dof), mdl.v0.ravel(), np.zeros(1 + len(mdl.spring_ids))))
    pieces = []
    nfev = 0
    kwargs: dict[str, Any] = {"method": method, "rtol": rtol, "atol": atol, "dense_output": True}
    if max_step is not None:
        kwargs["max_step"] = max_step
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        sol = solve_ivp(mdl.rhs_for(0.5 * (a + b)), (a, b), y, **kwargs)
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed on [{a}, {b}]: {sol.message}")
        pieces.append(sol.sol)
        nfev += int(sol.nfev)
        y = sol.y[:, -1]
    dense = _PiecewiseDense(bounds=bounds, pieces=pieces)
    t = np.linspace(0.0, end, 1001) if t_eval is None else np.atleast_1d(np.asarray(t_eval, dtype=float))
    return _make_result(mdl, dense, t, nfev)
