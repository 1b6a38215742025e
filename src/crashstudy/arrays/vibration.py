"""The model's free vibration: its longest natural period, which ``crashstudy validate`` and ``run`` compare
with ``end_time`` (:mod:`crashstudy.schema.plausible`, ``PERIOD_RATIO``).
"""

from __future__ import annotations

import math

import numpy as np

from crashstudy.arrays.compiler import Topology
from crashstudy.arrays.timestep import spring_stiffness_bound


def first_period(topo: Topology, params: np.ndarray) -> float:
    """The longest period [time] of the model's free vibration, 2 pi / omega_min over the modes that
    are not rigid-body motion, with each spring at its steepest slope (the critical step's stiffness)
    and fixed or driven directions held; inf with no vibration (no spring). Linearised about the
    initial positions; dampers and walls left out."""
    b, N, D = topo.blocks, topo.n_nodes, topo.dim
    P = params[:, None]
    kmax, _ = spring_stiffness_bound(topo, P[b["k"]], P[b["cx"]], P[b["cy_"]])
    x = params[b["position"]].reshape(N, D)
    K = np.zeros((N * D, N * D))
    for s, (i, j) in enumerate(topo.spring_nodes):
        d = x[j] - x[i]
        u = d / np.linalg.norm(d)
        ke = float(kmax[s, 0]) * np.outer(u, u)
        for a, bb, sign in ((i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)):
            K[a * D : (a + 1) * D, bb * D : (bb + 1) * D] += sign * ke
    held = topo.fixed.reshape(-1).copy()
    for n, d in zip(topo.pm_node, topo.pm_dir, strict=True):
        held[int(n) * D + int(d)] = True
    free = np.flatnonzero(~held)
    mass = np.repeat(params[b["mass"]], D)[free]
    if not free.size or free.size > 2000 or not np.all(mass > 0):
        return math.inf
    scale = 1.0 / np.sqrt(mass)
    w2 = np.linalg.eigvalsh(K[np.ix_(free, free)] * scale[:, None] * scale[None, :])
    top = float(np.max(np.abs(w2), initial=0.0))
    vib = w2[w2 > 1e-9 * top] if top > 0 else w2[:0]
    return 2.0 * math.pi / math.sqrt(float(vib.min())) if vib.size else math.inf
