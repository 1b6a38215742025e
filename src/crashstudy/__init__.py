"""crashstudy: lumped-parameter crash models run over whole design matrices.

Python API for notebooks::

    import crashstudy
    res = crashstudy.run_study("studies/helicopter-matrix.yaml")
    res.summary.groupby("impact_velocity")["peak_deceleration_g.cabin"].max()
    res.dataset["spring_force"].sel(spring="underfloor")
"""

from __future__ import annotations

import os as _os

if _os.environ.get(
    "NUMBA_CACHE_DIR"
):  # numba loads pickles from it: only a private folder (before numba reads it)
    from crashstudy.kernel.cache import secure_numba_cache as _secure

    _secure()

__version__ = "0.1.0"

__all__ = ["__version__", "open_results", "run_study", "simulate"]


def __getattr__(name: str):  # lazy: `crashstudy --help` must not pay for numba/xarray imports
    if name in ("run_study", "simulate"):
        from crashstudy.run import runner

        return getattr(runner, name)
    if name == "open_results":
        from crashstudy.results.store import open_results

        return open_results
    raise AttributeError(name)
