"""What the SPEC v2 spring feature tests (tests/test_spring_features_*.py) share: a node's history along
the spring axis and the elastoplastic spring of the impacts and preloads (``K``, ``KT``, ``FY``, ``MASS``)."""

from __future__ import annotations

from typing import Any

import numpy as np


def _along(out: Any, name: str, dim: int) -> np.ndarray:
    """History ``name`` of node ``b`` along the spring axis, variant 0."""
    axis = np.array([1.0] if dim == 1 else [0.6, 0.8])
    return out.histories[name][:, 1, :, 0] @ axis


# the elastoplastic spring
K, KT, FY = 4.0e4, 1.0e4, 2.0e3  # N/m, N/m, N: elastic limit ey = FY / K = 0.05 m
MASS = 10.0
