"""The fields of :class:`crashstudy.arrays.batch.Batch` that every variant shares (the model's topology).

They carry no variant axis: ``Batch.take`` passes them through, and the compiled kernels receive them as
the topology record ``T`` of :mod:`crashstudy.kernel.driver`, in this order (a record's field order is
part of a compiled kernel's signature).
"""

from __future__ import annotations

SHARED_FIELDS = (
    "spring_i",
    "spring_j",
    "material",
    "curve_a",
    "curve_b",
    "curve_off",
    "free",
    "load_node",
    "load_curve",
    "pm_node",
    "pm_dir",
    "pm_kind",
    "pm_curve",
    "wall_nodes",
    "knot_check",
    "rate_curve",
    "rate_off",
)
