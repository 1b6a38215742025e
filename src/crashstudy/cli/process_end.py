"""The end of a ``crashstudy run`` / ``simulate`` process: its exit code without the interpreter's teardown.

After a run the interpreter's own finalization (clearing every module, the garbage collection of what
numba, llvmlite, xarray and pandas hold, the compiled kernels' LLVM objects) took 0.5-0.6 CPU s and
1.3-1.4 s wall at load 5 on the 2-core machine after the last line was printed (10^6 x 86-step study;
benchmarks/results/speed25_*.md): time the user waits for, with every file already written and closed.
:func:`end` does what Python does before that teardown, in the same order, and then ends the process:
the non-daemon threads are waited for (``threading._shutdown``, which also stops idle thread pools), the
``atexit`` handlers run (multiprocessing's children joined, a kernel cache's temporary folder removed),
the standard streams are flushed; then ``os._exit``. Only the command line's own invocation (no
``argv`` given, the console script and ``python -m crashstudy``) ends this way, and only for the commands
in :data:`FAST_END` whose result files are closed when their handler returns; ``main(argv)`` called in a
process (tests, notebooks) returns as before.
"""

from __future__ import annotations

import atexit
import os
import sys
import threading

FAST_END = frozenset({"run", "simulate"})  # commands whose files are all closed when the handler returns


def end(code: int) -> None:
    """Wait for threads, run the ``atexit`` handlers, flush the streams and exit with ``code``."""
    shutdown = getattr(threading, "_shutdown", None)
    if shutdown is not None and threading.current_thread() is threading.main_thread():
        shutdown()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe (`crashstudy run ... | head`): nothing more to say
            pass
    os._exit(code)
