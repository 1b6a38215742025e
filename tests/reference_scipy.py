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

Modules: this one (the entry point, :func:`solve_reference`), reference_model.py (curves, loads and the
equations of motion), reference_parse.py (the model dict read into them) and reference_result.py (the
piecewise dense output and :class:`RefResult`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from reference_parse import SUPPORTED_MATERIALS, UNSUPPORTED_MATERIALS, _compile
from reference_result import RefResult, _make_result, _PiecewiseDense

__all__ = ["RefResult", "solve_reference", "SUPPORTED_MATERIALS", "UNSUPPORTED_MATERIALS"]


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
