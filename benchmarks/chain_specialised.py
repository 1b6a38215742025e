"""Hand-specialised loop for 1-D chains of ``nonlinear_elastic`` springs (benchmarks only).

A chain: node 0 fixed (the wall), nodes 1..S free, spring s joins nodes s-1 and s (drawn left to
right, ``e = u_s - u_{s-1}``), each following its own curve. The curves' shapes are compile-time
constants (the source of one fused, branch-free SIMD loop is written for the model's curves and compiled
once per model); everything a study varies comes in per variant: inverse masses, initial velocities,
each spring's force scale ``ys`` and abscissa scale ``xs`` (``F = ys * curve(e / xs)``), the step and
the step count (taken from crashstudy's batch, so element-steps are equal). It computes the summaries
crashstudy does (peak |force|, largest crush, absorbed energy per spring, peak |acceleration| per
node); :func:`check` compares its peak forces with crashstudy's for the same variants.

``fastmath`` and inverse masses: an upper bound on speed, not a twin (peak forces agree to ~1e-9).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numba as nb
import numpy as np

BLOCK = 256
ROW = BLOCK + 8  # row stride of the work array (rows 2 KiB apart would alias in L1)
_CACHE: dict[tuple[Any, ...], Any] = {}


@nb.njit(inline="always")
def _pos(x):  # pragma: no cover - compiled
    """max(0, x) as a select (numba's builtin max is a call that blocks vectorisation)."""
    return x if x > 0.0 else 0.0


@nb.njit(inline="always")
def _big(a, b):  # pragma: no cover - compiled
    return b if b > a else a


def _ramp_src(e: str, x: np.ndarray, y: np.ndarray) -> str:
    """Ramp sum y0 + s0 (e - x0) + sum_k ds_k max(0, e - x_k) with literal coefficients."""
    s = np.diff(y) / np.diff(x)
    out = f"({float(y[0])!r} + {float(s[0])!r} * ({e} - {float(x[0])!r}))"
    for k in range(1, len(x) - 1):
        out = f"({out} + {float(s[k] - s[k - 1])!r} * pos({e} - {float(x[k])!r}))"
    return out


def _source(curves: list[tuple[np.ndarray, np.ndarray]]) -> str:
    S = len(curves)
    L = [
        "def block(lo, hi, im, v0, ys, ixs, dt, n_steps, pf, mc, ie, pa):",
        "    B = hi - lo",
        f"    Z = np.zeros({8 * S * ROW})",
    ]
    # rows: u (S), v (S), fp (S), ep (S), pf (S), mc (S), ie (S), pa (S), a (S) [per node s+1], ...
    U, Vr, FP, EP, PF, MC, IE, PA = (k * S for k in range(8))
    L += ["    nmax = 0", "    for w in range(B):", "        nmax = max(nmax, n_steps[lo + w])"]
    L += [f"        Z[{Vr + s} * ROW + w] = v0[{s}, lo + w]" for s in range(S)]
    L += [
        "    for n in range(nmax + 1):",
        "        h0 = 1.0 if n > 0 else 0.5",
        "        wt = 1.0 if n > 0 else 0.0",
        "        for w in range(B):",
        "            k = lo + w",
        "            mk = 1.0 if n <= n_steps[k] else 0.0",
        "            h = dt[k]",
    ]
    for s, (x, y) in enumerate(curves):
        prev = f"Z[{U + s - 1} * ROW + w]" if s > 0 else "0.0"
        L.append(f"            e{s} = Z[{U + s} * ROW + w] - {prev}")
        L.append(f"            f{s} = ys[{s}, k] * {_ramp_src(f'(e{s} * ixs[{s}, k])', x, y)}")
    for s in range(S):  # node s+1: spring s pulls it back, spring s+1 forward
        fwd = f"f{s + 1}" if s + 1 < S else "0.0"
        L.append(f"            a{s} = ({fwd} - f{s}) * im[{s}, k]")
    for s in range(S):
        L += [
            f"            Z[{IE + s} * ROW + w] += (mk * wt) * (0.5 * (f{s} + Z[{FP + s} * ROW + w]) * (e{s} - Z[{EP + s} * ROW + w]))",
            f"            Z[{PF + s} * ROW + w] = big(Z[{PF + s} * ROW + w], mk * abs(f{s}))",
            f"            Z[{MC + s} * ROW + w] = big(Z[{MC + s} * ROW + w], -(mk * e{s}))",
            f"            Z[{PA + s} * ROW + w] = big(Z[{PA + s} * ROW + w], mk * abs(a{s}))",
            f"            Z[{Vr + s} * ROW + w] += mk * ((h0 * h) * a{s})",
            f"            Z[{U + s} * ROW + w] += mk * (h * Z[{Vr + s} * ROW + w])",
            f"            Z[{FP + s} * ROW + w] = f{s}",
            f"            Z[{EP + s} * ROW + w] = e{s}",
        ]
    L += ["    for w in range(B):"]
    for s in range(S):
        L += [
            f"        pf[{s}, lo + w] = Z[{PF + s} * ROW + w]",
            f"        mc[{s}, lo + w] = Z[{MC + s} * ROW + w]",
            f"        ie[{s}, lo + w] = Z[{IE + s} * ROW + w]",
            f"        pa[{s}, lo + w] = Z[{PA + s} * ROW + w]",
        ]
    return "\n".join(L) + "\n"


def _compiled(curves: list[tuple[np.ndarray, np.ndarray]]) -> Any:
    key = tuple((tuple(x), tuple(y)) for x, y in curves)
    if key not in _CACHE:
        ns: dict[str, Any] = {"np": np, "ROW": ROW, "pos": _pos, "big": _big}
        exec(compile(_source(curves), "<chain_specialised>", "exec"), ns)  # noqa: S102 - our own source
        _CACHE[key] = nb.njit(nogil=True, fastmath=True, error_model="numpy")(ns["block"])
    return _CACHE[key]


def inputs(b: Any) -> dict[str, np.ndarray]:
    """The per-variant inputs of a crashstudy batch of a chain model: inverse masses and initial velocities
    of nodes 1..S, each spring's curve factors (Batch.cfac), the steps."""
    S = len(b.spring_i)
    assert np.array_equal(b.spring_i, np.arange(S)) and np.array_equal(b.spring_j, np.arange(1, S + 1)), (
        "not a chain"
    )
    assert np.all(b.sign == 1.0), "springs drawn left to right"
    ca = b.curve_a
    return {
        "im": np.ascontiguousarray(1.0 / b.mass[1:]),
        "v0": np.ascontiguousarray(b.v0[1:, 0]),
        "ys": np.ascontiguousarray(b.cfac[0, ca]),
        "ixs": np.ascontiguousarray(1.0 / b.cfac[1, ca]),
        "dt": b.dt,
        "n_steps": b.n_steps.astype(np.int64),
    }


def shapes(b: Any) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each spring's curve as written (x, y), from the batch (the same in every variant: asserted)."""
    out = []
    for c in b.curve_a:
        a, e = int(b.curve_off[c]), int(b.curve_off[c + 1])
        x, y = b.bx[a:e], b.by[a:e]
        assert np.all(x == x[:, :1]) and np.all(y == y[:, :1]), "a curve's points vary: no constant shape"
        out.append((x[:, 0].copy(), y[:, 0].copy()))
    return out


def run(
    curves: list[tuple[np.ndarray, np.ndarray]], inp: dict[str, np.ndarray], threads: int = 2
) -> dict[str, np.ndarray]:
    """Integrate every variant of ``inp`` (see :func:`inputs`); summaries with springs / nodes on axis 0."""
    fn = _compiled(curves)
    S, V = inp["ys"].shape
    out = {k: np.zeros((S, V)) for k in ("peak_force", "max_crush", "absorbed_energy", "peak_acceleration")}
    starts = list(range(0, V, BLOCK)) + [V]
    args = (
        inp["im"],
        inp["v0"],
        inp["ys"],
        inp["ixs"],
        inp["dt"],
        inp["n_steps"],
        out["peak_force"],
        out["max_crush"],
        out["absorbed_energy"],
        out["peak_acceleration"],
    )
    cuts = np.linspace(0, len(starts) - 1, min(len(starts) - 1, 8 * threads) + 1).astype(int)

    def part(k: int) -> None:
        for bi in range(cuts[k], cuts[k + 1]):
            fn(starts[bi], starts[bi + 1], *args)

    with ThreadPoolExecutor(threads) as pool:
        list(pool.map(part, range(len(cuts) - 1)))
    return out


def check(loop: dict[str, np.ndarray], peak_force: np.ndarray) -> float:
    """Largest relative difference of the loop's peak forces to crashstudy's (S, V)."""
    return float(np.max(np.abs(loop["peak_force"] - peak_force) / np.maximum(np.abs(peak_force), 1e-300)))
