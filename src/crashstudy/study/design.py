"""Sampled designs: the rows of a study's ``design:`` block (docs/design.md).

A design draws ``n`` points in the unit hypercube, one coordinate per axis, with scipy's
quasi-Monte Carlo engines (``scipy.stats.qmc``: Latin hypercube, scrambled Sobol', scrambled
Halton) or plain pseudo-random numbers, seeded so that the same file gives the same rows. Each
coordinate is then mapped through its axis's distribution (the inverse CDF of ``scipy.stats``):

- ``uniform: [low, high]``;
- ``normal: [mean, sd]``;
- ``lognormal: [mu, sigma]``: ``exp`` of a normal with mean ``mu`` and standard deviation ``sigma``;
- ``truncnormal: [mean, sd, low, high]``: a normal cut to ``[low, high]`` (a mass or a stiffness
  that must stay positive).

Two designs exist for the sensitivity methods of SALib (``crashstudy sensitivity``), whose
estimators need their own sample structure: ``saltelli`` (Sobol' indices; ``n`` base points give
``n (2 d + 2)`` rows) and ``morris`` (``n`` trajectories of ``d + 1`` rows on a 4-level grid).

The rows form one dimension of the study, after ``matrix`` and ``zip``: the design's axes vary
together along it (like a zip group) and the whole design is crossed with the matrix.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

_EDGE = 1e-12  # unit coordinates are kept inside (0, 1): the inverse CDF of a normal is infinite at 0 and 1


def rows(method: str, n: int, seed: int, dists: dict[str, tuple[str, list[float]]]) -> dict[str, np.ndarray]:
    """The design's rows: axis path -> values (one per row), for ``dists`` (path -> (name, parameters))."""
    unit = unit_rows(method, n, seed, len(dists))
    return {
        path: to_distribution(name, params, unit[:, k])
        for k, (path, (name, params)) in enumerate(dists.items())
    }


def n_rows(method: str, n: int, d: int) -> int:
    """How many rows a design of ``n`` (base points / trajectories) over ``d`` axes has."""
    return n * (2 * d + 2) if method == "saltelli" else n * (d + 1) if method == "morris" else n


def unit_rows(method: str, n: int, seed: int, d: int) -> np.ndarray:
    """(rows, d) points in the open unit hypercube."""
    from scipy.stats import qmc

    if method == "random":
        u = np.random.default_rng(seed).random((n, d))
    elif method == "lhs":
        u = qmc.LatinHypercube(d, seed=np.random.default_rng(seed)).random(n)
    elif method in ("sobol", "halton"):
        engine = (qmc.Sobol if method == "sobol" else qmc.Halton)(
            d, scramble=True, seed=np.random.default_rng(seed)
        )
        with (
            warnings.catch_warnings()
        ):  # Sobol' balance is best at powers of two; any n is still a valid design
            warnings.simplefilter("ignore", UserWarning)
            u = engine.random(n)
    elif method in ("saltelli", "morris"):
        u = _salib_rows(method, n, seed, d)
    else:  # the schema (schema/study.py Design.method) lets only the methods above through
        raise ValueError(f"unknown design method {method!r}")
    return np.clip(u, _EDGE, 1.0 - _EDGE)


def salib_problem(d: int) -> dict[str, Any]:
    """The SALib problem of a design over ``d`` axes, in unit coordinates (the distributions are
    applied afterwards, so the indices are those of the mapped inputs)."""
    return {"num_vars": d, "names": [f"x{k}" for k in range(d)], "bounds": [[0.0, 1.0]] * d}


def _salib_rows(method: str, n: int, seed: int, d: int) -> np.ndarray:
    if method == "saltelli":
        return saltelli_rows(n, seed, d)
    return morris_rows(n, seed, d)


def morris_rows(n: int, seed: int, d: int, levels: int = 4) -> np.ndarray:
    """The rows of ``SALib.sample.morris.sample(salib_problem(d), n, num_levels=levels, seed=seed)``, the
    same numbers in the same order, with SALib's random draws made in its order (per trajectory: a
    shuffled order of the axes, a direction per axis, a start level per axis) and the trajectories built
    with array operations: SALib builds each with matrix products (20 s for n = 10^5, this 3.5 s).
    Trajectory t starts at x* and moves axis perm[k] at step k + 1 by +-delta: row r holds
    ``x* + delta/2 ((2 [perm < r] - 1) D + 1)`` (tests/test_design.py compares it with SALib)."""
    rng = np.random.default_rng(seed)
    delta = levels / (2.0 * (levels - 1))
    grid = np.linspace(0.0, 1.0 - delta, levels // 2)
    perm = np.empty((n, d), dtype=np.int64)
    up = np.empty((n, d), dtype=np.int64)
    start = np.empty((n, d), dtype=np.int64)
    for t in range(n):  # SALib's draws: shuffle, choice([-1, 1], d), choice(grid, d) (choice draws integers)
        p = np.arange(d)
        rng.shuffle(p)
        perm[t] = p
        up[t] = rng.integers(0, 2, d)
        start[t] = rng.integers(0, len(grid), d)
    moved = (perm[:, None, :] < np.arange(d + 1)[None, :, None]).astype(np.float64)  # (n, d + 1, d)
    sign = np.array([-1.0, 1.0])[up][:, None, :]
    out = grid[start][:, None, :] + (delta / 2.0) * ((2.0 * moved - 1.0) * sign + 1.0)
    return out.reshape(n * (d + 1), d)


def saltelli_rows(n: int, seed: int, d: int) -> np.ndarray:
    """The rows of ``SALib.sample.sobol.sample(salib_problem(d), n, calc_second_order=True, seed=seed)``,
    the same numbers in the same order, built with array operations: SALib fills them in a Python loop
    (34 s for n = 10^6 on a loaded core). Per base point i of a scrambled Sobol' sequence in 2d
    dimensions (A = its first d coordinates, B = the last d): A, then A with column k from B (k = 1..d),
    then B with column k from A (k = 1..d), then B (tests/test_design.py compares it with SALib)."""
    from scipy.stats import qmc

    with (
        warnings.catch_warnings()
    ):  # Sobol' balance is best at powers of two; its estimator is valid for any n
        warnings.simplefilter("ignore")
        base = qmc.Sobol(d=2 * d, scramble=True, seed=seed).random(n)
    a, b = base[:, :d], base[:, d:]
    out = np.empty((n, 2 * d + 2, d))
    out[:, 0] = a
    eye = np.eye(d, dtype=bool)
    out[:, 1 : d + 1] = np.where(eye[None], b[:, None, :], a[:, None, :])
    out[:, d + 1 : 2 * d + 1] = np.where(eye[None], a[:, None, :], b[:, None, :])
    out[:, 2 * d + 1] = b
    return out.reshape(n * (2 * d + 2), d)


def to_distribution(name: str, p: list[float], u: np.ndarray) -> np.ndarray:
    """Map unit coordinates ``u`` through the inverse CDF of distribution ``name`` with parameters ``p``."""
    from scipy import stats

    if name == "uniform":
        return p[0] + u * (p[1] - p[0])
    if name == "normal":
        return np.asarray(stats.norm.ppf(u, loc=p[0], scale=p[1]))
    if name == "lognormal":
        return np.exp(np.asarray(stats.norm.ppf(u, loc=p[0], scale=p[1])))
    if name == "truncnormal":
        a, b = (p[2] - p[0]) / p[1], (p[3] - p[0]) / p[1]
        return np.asarray(stats.truncnorm.ppf(u, a, b, loc=p[0], scale=p[1]))
    raise ValueError(f"unknown distribution {name!r}")
