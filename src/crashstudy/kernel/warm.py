"""A compile in its own process: ``python -m crashstudy.kernel.warm JOB`` (started by
:func:`crashstudy.kernel.choice.start_background`).

JOB is JSON: the kernels to compile (``generic``, ``generated``), the run's history names, varying
curves and constant curves, and a ``.npz`` of one variant of the run's batch (read with
``allow_pickle=False``: only plain arrays). Each kernel is compiled by running that variant for one
step, which leaves it in numba's disk cache. One compile per cache at a time: the process holds an
exclusive lock on ``compile.lock`` in the cache folder and exits at once if another holds it.
"""

from __future__ import annotations

import fcntl
import json
import os
import sys
from types import SimpleNamespace
from typing import Any

import numpy as np


def main(argv: list[str]) -> int:
    from crashstudy.kernel.cache import checked_dir
    from crashstudy.kernel.choice import LOCK_NAME

    job = json.loads(argv[0])
    folder = checked_dir()
    try:
        with np.load(job["npz"], allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    finally:
        if os.path.dirname(os.path.abspath(job["npz"])) == str(folder):
            os.unlink(job["npz"])
    b: Any = SimpleNamespace(**arrays)  # a Batch's arrays (the kernels read only its fields)
    b.n_steps[:] = 1
    histories = tuple(job["histories"])
    with open(folder / LOCK_NAME, "a") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return 0  # another process compiles; it leaves the kernel in the same cache
        for kernel in job["kernels"]:
            if kernel == "generic":
                from crashstudy.kernel.compiled import run_compiled

                run_compiled(b, histories, 1)
            else:
                from crashstudy.kernel.generated import run_generated

                run_generated(b, histories, 1, frozenset(job["vary"]), list(job["const"]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
