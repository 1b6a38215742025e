"""What one task computed: :class:`ChunkResult`, handed from a worker to the writer.

A module of its own (NumPy and the kernel's output only) so that a ``--jobs`` worker or a Dask worker
that returns one imports neither the writer (netCDF4) nor the reader (pandas, xarray).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from crashstudy.kernel.output import KernelOutput


@dataclass
class ChunkResult:
    """Results of variants ``index`` (sorted global numbers) as computed by one task."""

    index: np.ndarray
    out: KernelOutput
    dt: np.ndarray
    dt_crit: np.ndarray
    dt_control: np.ndarray  # (V,) object: texts
    reasons: np.ndarray  # (V,) object: texts, "" where ok
    hashes: np.ndarray  # (V, HASH_WORDS) uint64
    error_estimate: np.ndarray  # (V,) NaN unless the model asks for accuracy_check
    criteria: Any = None  # crashstudy.metrics.record.ChunkCriteria of a model with metrics, else None
    curve_end: np.ndarray | None = None  # (S, V) past_curve_end codes (crashstudy.results.curve_ends)

    @property
    def size(self) -> int:
        """Variants computed."""
        return len(self.index)

    @property
    def n_failed(self) -> int:
        return int(np.count_nonzero(self.out.status))
