"""The crash criteria as a compile that a run needs beside its kernel.

The kernel package compiles them on the other core while it compiles a kernel, in its warm-up process
(:mod:`crashstudy.kernel.warm`), but knows them only through the protocol
:class:`crashstudy.kernel.choice.Companion`: :data:`CRITERIA` says what they are called, how long they take,
which lock they compile under, whether they are compiled, and which function compiles them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CriteriaCompile:
    """The crash criteria and the filter of the ``filtered_acceleration`` history, compiled once per machine."""

    name: str = "criteria"  # what the kernel choice calls this compile (``Decision.foreground`` ...)
    label: str = "the crash criteria"  # what messages call it
    seconds: float = (
        15.0  # [s] expected compile time (15.3 CPU s on an empty cache, 2026-11-27, numba 0.68.1)
    )
    lock: str = "criteria.lock"  # its own lock in the kernel cache folder, so it compiles beside a kernel
    target: str = "crashstudy.metrics.warmup:compile_criteria"  # what the warm-up process calls

    def ready(self) -> bool:
        """Whether the criteria are compiled (in this process or in numba's disk cache)."""
        from crashstudy.kernel.cache import compiled_or_cached
        from crashstudy.metrics import criteria

        return compiled_or_cached(criteria._driver)


CRITERIA = CriteriaCompile()


def compile_criteria() -> None:
    """Compile the crash criteria and the filter of the filtered_acceleration history (a short pulse)."""
    from crashstudy.metrics import criteria, interpreted

    interpreted.compile_from_now()  # else this short pulse would run as plain Python, compiling nothing
    acc = np.zeros((1, 8, 1))
    criteria.compute(
        acc, np.array([8]), np.array([1e-4]), np.ones((1, 1)), np.ones(1), 180, criteria.CRITERIA, 9.80665
    )
    criteria.j211_filter(acc[:, :, 0], np.array([8]), np.array([1e-4]), 180)
