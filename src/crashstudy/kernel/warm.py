"""A compile in its own process: ``python -m crashstudy.kernel.warm JOB`` (started by
:func:`crashstudy.kernel.choice.start_background`).

JOB is JSON: the kernels to compile (``generic``, ``generated``, or a companion alone: a compile the
run needs beside its kernel, :class:`crashstudy.kernel.choice.Companion`, e.g. the crash criteria; the job
then names its ``lock``, of its own so that it compiles beside a kernel, and the function to ``call``,
``module:function`` of a crashstudy module), the run's history names, varying curves and constant
curves, and a ``.npz`` of one variant of the run's batch (read with ``allow_pickle=False``: only plain
arrays). Each kernel is compiled by running that variant for one
step, which leaves it in numba's disk cache. One compile per cache at a time: the process holds an
exclusive lock on ``compile.lock`` in the cache folder and writes into it what it compiles
(:func:`crashstudy.kernel.compile_lock.write_holder`: the job's ``keys`` and ``seconds``). When another
process holds the lock, a background job (run for later) exits at once; a job a run waits for
(``must``) compiles anyway, privately beside the holder (numba writes each cache file atomically).
"""

from __future__ import annotations

import fcntl
import importlib
import json
import os
import sys
from types import SimpleNamespace
from typing import Any

import numpy as np


def main(argv: list[str]) -> int:
    from crashstudy.kernel.cache import checked_dir
    from crashstudy.kernel.choice import LOCK_NAME
    from crashstudy.kernel.compile_lock import write_holder

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
    record = tuple(job.get("record", []))
    call = job.get("call")
    if call is not None and not str(call).startswith("crashstudy."):
        raise ValueError(f"warm-up calls only crashstudy functions, not {call!r}")
    with open(folder / (os.path.basename(job["lock"]) if call is not None else LOCK_NAME), "a+") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            write_holder(
                lock, list(job.get("keys", job["kernels"])), [float(s) for s in job.get("seconds", [])]
            )
        except OSError:
            if not job.get("must"):
                return 0  # another process compiles; it leaves the kernel in the same cache
        if call is not None:  # a companion compile (the crash criteria)
            module, _, name = str(call).partition(":")
            getattr(importlib.import_module(module), name)()
            return 0
        for kernel in job["kernels"]:
            if kernel == "generic":
                from crashstudy.kernel.compiled import run_compiled

                run_compiled(b, histories, 1, record=record)
            else:
                from crashstudy.kernel.generated import run_generated

                run_generated(b, histories, 1, frozenset(job["vary"]), list(job["const"]), record)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
