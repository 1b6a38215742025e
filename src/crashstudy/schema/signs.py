"""Sign rules of a model's numbers, written once for a model file and for every study variant.

Two slips pass every field's own check and end in numbers no engineer would believe:

- **a node that starts behind a rigid wall** (a wall point typed in mm in an SI model): the wall
  catches the node on its first step and throws it to the plane, 2.5e7 g and 658 km of crush in 1-D,
  "numerical instability" in 2-D. A node the wall holds must start on the side its normal points to,
  or on the plane.
- **a material curve whose force has the wrong sign** (positive force in compression): a negative
  stiffness, which pushes the nodes further the more they are deformed. The force of a
  ``nonlinear_elastic`` curve, both ``general_nonlinear`` curves and a ``nonlinear_damper`` curve has
  the sign of its elongation (or elongation rate), or is zero (a tension-free part is legal). The
  rule is checked on a ``nonlinear_elastic`` curve and a ``general_nonlinear`` loading curve; the
  unloading and damper curves pass through the origin and increase, so they obey it already, and a
  ``crush`` curve has its own rule (a compression part with a negative force; it carries ``min(0, L)``).

Both functions take arrays with a trailing variant axis ``V`` (1 for a model file): the schema
(:mod:`crashstudy.schema.checks`) and the vectorised check of study axis values
(:func:`crashstudy.arrays.parameter_checks.check_parameters`) call the same code.
"""

from __future__ import annotations

import numpy as np

from crashstudy.vocabulary.materials import MATERIALS

#: relative round-off below which a node counts as on the wall plane, and a force as zero
ROUND_OFF = 1.0e-12
FORCE_ZERO = 1.0e-9
#: materials whose (loading) curve's force must have the sign of the elongation; an increasing unloading
#: curve and a non-decreasing damper curve through the origin have it already, a crush curve its own rule
SIGNED_TYPES = tuple(m.name for m in MATERIALS if m.curves and m.curves[0].rule == "signed")


def depth_behind_walls(
    x: np.ndarray, free: np.ndarray, point: np.ndarray, normal: np.ndarray, held: np.ndarray
) -> np.ndarray:
    """How far each node starts behind each wall, (W, N, V) [length]; 0 where it may start.

    ``x`` (N, D, V) node positions, ``free`` (N, D) the directions a node moves in, ``point`` and
    ``normal`` (W, D, V) the walls, ``held`` (W, N) the nodes each wall stops. A node the wall does not
    hold, or one that cannot move along the wall's normal (fixed there: the wall never acts on it), may
    start anywhere; a zero normal (refused on its own) gives 0."""
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = normal / np.sqrt(np.sum(normal * normal, axis=1, keepdims=True))
    unit = np.nan_to_num(unit, nan=0.0, posinf=0.0, neginf=0.0)
    rel = x[None, :, :, :] - point[:, None, :, :]  # (W, N, D, V)
    dist = np.sum(rel * unit[:, None, :, :], axis=2)  # (W, N, V), > 0 on the side the normal points to
    size = np.sum(np.abs(x[None]) + np.abs(point[:, None]), axis=2)
    moves = np.any(free[None, :, :, None] & (unit[:, None, :, :] != 0.0), axis=2)
    behind = held[:, :, None] & moves & (dist < -ROUND_OFF * size)
    return np.where(behind, -dist, 0.0)


def wrong_sign_points(xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Knots (n, V) of curves ``xs``, ``ys`` whose force (y) has the sign opposite to the elongation (x).

    A force within :data:`FORCE_ZERO` of the curve's largest |y| counts as zero (the origin's round-off)."""
    scale = np.max(np.abs(ys), axis=0, keepdims=True)
    return (xs * ys < 0.0) & (np.abs(ys) > FORCE_ZERO * scale)


def behind_message(node: str, depth: float, wall: str, length: str, more: int = 0) -> str:
    """Why a node behind a wall is refused, and what to check."""
    others = f" (and {more} more of its nodes)" if more else ""
    return (
        f"node {node!r} starts {depth:.6g} {length} behind wall {wall!r}{others}: a node the wall stops must "
        "start on the side its normal points to, or on the plane (check the wall's point, its normal and "
        "the node's position, and that they are in the model's length unit)"
    )


def sign_message(cid: str, k: int, x: float, y: float, use: str) -> str:
    """Why a material curve of the wrong sign is refused, naming the offending point."""
    part = "compression (x < 0)" if x < 0 else "tension (x > 0)"
    want = "<= 0" if x < 0 else ">= 0"
    return (
        f"the {use} curve {cid!r} has force {y:g} at x = {x:g} (point {k}): in {part} its force must be "
        f"{want}, of the sign of the elongation (compression forces are negative); the wrong sign is a "
        "negative stiffness that pushes the nodes apart the more they are deformed"
    )
