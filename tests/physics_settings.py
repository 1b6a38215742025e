"""What the physics tests of the central-difference solver (tests/test_physics_*.py) share: the kernel
of their long runs (``FAST``) and a relative error (``_rel``), and their settings.

Models run at DEFAULT settings (no ``time_step`` key, i.e. ``{tolerance: 1e-3}``) unless the test is about
the time step itself. Units are SI unless a model says otherwise.

Where a model sets ``output.interval``, the interval is chosen coarser than the step the tolerance
asks for: the solver never steps over a sample, so the default sampling (end_time / 1000) would
shrink the step and the test would no longer check the step that the default tolerance chooses."""

from __future__ import annotations

#: the kernel of the tests whose runs are long for the NumPy reference (0.5-1.7 s each): the automatic
#: choice ("compiled") takes the reference when it expects it to finish within a compiled kernel's load
#: time, even with the generic kernel loaded; the generic kernel is bitwise the reference on walls,
#: prescribed motion and every material (tests/test_kernel_twins.py)
FAST = "generic"


def _rel(got: float, expected: float) -> float:
    return abs(float(got) / float(expected) - 1.0)
