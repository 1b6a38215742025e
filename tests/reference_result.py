"""The scipy reference solver's results: the piecewise dense output of its integration and
:class:`RefResult`, the histories on the requested times. Part of the independent scipy reference solver
(reference_scipy.py, which describes its scope, physics and numerics); like it, it does not import
``crashstudy``."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar

from reference_model import _Model

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
