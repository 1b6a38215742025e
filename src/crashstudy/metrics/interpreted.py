"""The crash criteria without a compiler: their compiled functions run as plain Python.

On a machine where the criteria are not compiled yet, compiling them takes about 7 s
(``benchmarks/results/compile_costs.md``), while a small record (one ``simulate``, a short study)
takes the same functions milliseconds as plain Python (about 30 us per sample for all criteria).
:func:`driver_for` therefore hands out the numba function's own Python code (``py_func``, with every
numba function it calls replaced the same way: nothing is written twice) until a process has
interpreted ``PLAIN_MAX_SAMPLES`` samples, and the compiled one after that or once it is compiled.
The results are the same to the last bit on the test signals (tests/test_criteria_convergence_and_batching.py): numba
compiles without fast-math, so every operation rounds as in Python.
"""

from __future__ import annotations

import types
from typing import Any

from numba.core.registry import CPUDispatcher

from crashstudy.kernel.cache import compiled_or_cached

PLAIN_MAX_SAMPLES = 100_000  # samples a process interprets before it compiles (~3 s of Python, < the compile)
_SPENT = [0]  # samples interpreted in this process
_PLAIN: dict[Any, Any] = {}


def plain(fn: Any) -> Any:
    """Numba function ``fn`` as a plain Python function: its ``py_func`` with every numba function it
    calls (a global of its module) replaced by its plain version."""
    if fn in _PLAIN:
        return _PLAIN[fn]
    py = fn.py_func
    names = dict(py.__globals__)
    out = types.FunctionType(py.__code__, names, py.__name__, py.__defaults__, py.__closure__)
    _PLAIN[fn] = out
    for name in py.__code__.co_names:
        if isinstance(names.get(name), CPUDispatcher):
            names[name] = plain(names[name])
    return out


def driver_for(fn: Any, samples: int) -> tuple[Any, bool]:
    """(the function to call, whether it is compiled) for a call on ``samples`` samples: ``fn`` itself
    when it is compiled (in this process or numba's disk cache) or this process has interpreted enough,
    else its plain Python version (counted)."""
    if compiled_or_cached(fn) or _SPENT[0] + samples > PLAIN_MAX_SAMPLES:
        return fn, True
    _SPENT[0] += samples
    return plain(fn), False


def compile_from_now() -> None:
    """Every later call in this process takes the compiled functions (a process that compiles them)."""
    _SPENT[0] = PLAIN_MAX_SAMPLES
