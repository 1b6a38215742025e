"""The generic kernel's stages (``generic_block.stage``): compiled once per argument types and linked into
their caller, never compiled to machine code on their own (benchmarks/results/generic_compile.md, the cold
compile), with the flags of the ``numba.njit`` functions they replaced, so that the kernel's results do not
change (bitwise: test_kernel_twins).

Independent truth: the same Python function run by the interpreter; numba's own compile events (a
``numba.njit`` function reports one per compile, a stage none: it has no dispatcher of its own).
"""

from __future__ import annotations

import numba as nb
import numpy as np
import pytest
from numba.core import event

from crashstudy.kernel.generic_block import stage


def _scale(x, k):  # pragma: no cover - compiled
    for i in range(x.shape[0]):
        x[i] = x[i] / k
    return x.shape[0], x[0] + x[-1]


scale = stage(_scale)


@nb.njit
def _caller(x, k):  # pragma: no cover - compiled
    n, ends = scale(x, k)
    return n, ends


def test_a_stage_is_linked_into_its_caller_with_njit_results_and_errors() -> None:
    x = np.linspace(-1.0, 3.0, 7)
    want = x.copy()
    n_want, ends_want = _scale(want, 3.0)
    with event.install_recorder("numba:compile") as rec:
        n, ends = _caller(x, 3.0)
    assert (n, ends) == (n_want, ends_want) and np.array_equal(x, want)  # bitwise: same float divisions
    compiled = {e.data["dispatcher"].py_func.__name__ for _, e in rec.buffer if e.is_start}
    assert compiled == {"_caller"}  # the stage: no dispatcher of its own, compiled inside its caller
    # numba.njit's error model ("python"): a division by zero raises, as in the njit function it replaced
    with pytest.raises(ZeroDivisionError):
        _caller(x, 0.0)


def _double(x):  # pragma: no cover - compiled
    for i in range(x.shape[0]):
        x[i] = 2.0 * x[i]


double = stage(_double, inline=True)


@nb.njit
def _double_caller(x):  # pragma: no cover - compiled
    double(x)


def test_an_inline_stage_is_inlined_into_its_caller() -> None:
    x = np.linspace(-1.0, 3.0, 7)
    want = 2.0 * x
    _double_caller(x)
    assert np.array_equal(x, want)
    calls = [
        ln for ln in _double_caller.inspect_llvm(_double_caller.signatures[0]).splitlines() if " call " in ln
    ]
    assert not [ln for ln in calls if "_double" in ln.replace("_double_caller", "")]  # no call left: inlined


def _allocate(n):  # pragma: no cover - compiled
    return np.zeros(n).sum()


allocate = stage(_allocate)  # nrt=False (the default): numba refuses to lower an allocation


@nb.njit
def _allocate_caller(n):  # pragma: no cover - compiled
    return allocate(n)


def test_a_stage_without_nrt_cannot_allocate() -> None:
    # np.zeros' own implementation, typed without NRT, returns an array that is not its argument
    with pytest.raises(Exception, match="Only accept returning of array passed into the function"):
        _allocate_caller(3)
