"""Which kernel integrates a batch: the one expected to finish first on this machine, compilation
included.

The three kernels give bitwise equal results (docs/kernels.md), so the choice changes only time. A
cost model in seconds, measured on the 2-core reference machine (benchmarks/results/cold_start.md):

- NumPy reference: no compilation; ``REF_STEP + REF_SPRING_STEP * S`` per time step of the longest
  variant (Python overhead), plus ``REF_ELEMENT_STEP`` per element-step (spring x step x variant);
- generic (numba): compiled once per machine, ``GENERIC_COMPILE`` s, then ``GENERIC_RATE``
  element-steps/s;
- generated (numba, one per model shape): compiled once per shape, :func:`generated_compile_seconds`
  (2.6-10 s for the example models, benchmarks/results/compile_costs.md), then ``GENERATED_RATE``
  element-steps/s;
- a companion compile (:class:`Companion`: the crash criteria of a model with ``metrics:``,
  :data:`crashstudy.metrics.warmup.CRITERIA`): compiled once per machine, whatever kernel runs; a compile
  in the foreground does it beside the kernel's, on the other core.

:func:`pick` takes, per chunk, the fastest kernel that is already compiled; the NumPy reference is
always ready, so a tiny run never waits for a compiler. When a whole run would take the reference
more than ``background_min_seconds()`` and a fast kernel is missing, :func:`plan_start` says what to
compile and :func:`start_background` compiles it in a separate, low-priority process (one at a time
per cache, under a lock) while the run goes on with the reference in small chunks; the next chunk
after the compile finished runs compiled. The compiled kernel stays in the cache, so a repeat of the
study (and every study of the same model shape) runs compiled from its first chunk.

Without a background process (``CRASHSTUDY_BACKGROUND_COMPILE=0``, or a worker of a process pool or
Dask cluster, which never starts one) a chunk compiles a kernel in the foreground (the one quicker to
compile and run, usually this shape's generated one) only when the reference would take longer than
compiling and running it (:func:`pick`), so a study is never slower than the generic kernel alone by
more than the estimate's error.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, cast

import numpy as np

from crashstudy import environment
from crashstudy.kernel import compile_lock
from crashstudy.kernel.cache import cache_dir, compiled_or_cached, why_not_private
from crashstudy.kernel.decision import StartPlan
from crashstudy.vocabulary.codes import GENERAL, KernelName

if TYPE_CHECKING:
    from crashstudy.arrays.batch import Batch

# the NumPy reference, fitted to benchmarks/results/reference_cost.md (one spring 299 us/step, frontal one
# variant 1891 us/step, frontal 1000 variants 3486 us/step; quiet 2-core machine, 2026-11-27)
REF_STEP = 72e-6  # [s] per time step of the NumPy reference, whatever the batch
REF_SPRING_STEP = 227e-6  # [s] per time step and spring
REF_ELEMENT_STEP = 0.2e-6  # [s] per element-step (spring x step x variant)
# the compiled kernels on 2 threads, frontal 10^4 variants, histories off, quiet 2-core machine of 2026-11-27
# (benchmarks/results/quiet_2026-11-27/throughput.md: 1.36e8 and 1.95e8; the machine of 11-22 ran 3.1e8 and
# 9.8e8: these rates are of the machine, and the choice only needs them within a factor of ~2)
GENERIC_RATE = 1.4e8  # [element-steps/s] generic kernel, 2 threads
GENERATED_RATE = 2.0e8  # [element-steps/s] generated kernel, 2 threads
# [s] compiling the generic kernel (once per machine): the lead's quiet-machine 79 s at 1ab7358 times the
# side-by-side ratio 0.63 of its stages compiled once each, times 0.82 of its records read once and its
# stages linked instead of dispatchers (benchmarks/results/generic_compile.md)
GENERIC_COMPILE = 41.0
GEN_BASE, GEN_GENERAL, GEN_SPRING, GEN_WALL, GEN_RECORD = (
    2.0,
    3.5,
    0.4,
    1.0,
    1.0,
)  # [s] generated_compile_seconds
GEN_SPRING2 = 0.045  # [s] per spring squared beyond GEN_SMALL: one unrolled function (compile_springs.md)
GEN_SMALL = 8  # springs up to which the generated compile grows linearly (compile_costs.md)
LOAD = 0.3  # [s] loading a compiled kernel from the disk cache (once per process)
BACKGROUND_MIN = 2.0  # [s] of reference time of a run above which missing kernels compile in the background
KERNELS = ("reference", "generic", "generated")
LOCK_NAME = "compile.lock"  # held by the process compiling kernels
REF_CHUNK = 1024  # variants per chunk while the reference runs and a compile may finish
RECORDING = KERNELS  # kernels that record the per-step acceleration of metric nodes (crash criteria)
_LOADED: set[str] = set()  # kinds of compiled kernel loaded in this process
_BACKGROUND: list[subprocess.Popen[bytes]] = []  # background compiles started by this process


class Companion(Protocol):
    """A compile a run needs besides its kernel, done beside the kernel's on the other core (the crash
    criteria: :data:`crashstudy.metrics.warmup.CRITERIA`). The kernel package knows it only through this,
    as it knows the metrics' per-step record only through :class:`crashstudy.kernel.entry.Recorder`."""

    @property
    def name(self) -> str: ...  # what decisions and lock holders call it ("criteria")

    @property
    def label(self) -> str: ...  # what messages call it ("the crash criteria")

    @property
    def seconds(self) -> float: ...  # [s] expected compile time

    @property
    def lock(self) -> str: ...  # its lock file in the kernel cache folder (not LOCK_NAME: it compiles beside)

    @property
    def target(
        self,
    ) -> str: ...  # "module:function" that compiles it, called by ``python -m crashstudy.kernel.warm``

    def ready(self) -> bool: ...  # compiled, in this process or in numba's disk cache


def kernel_override() -> KernelName:
    """The kernel ``CRASHSTUDY_KERNEL`` asks for: "compiled" (unset: choose), or one of ``KERNELS``."""
    return cast(KernelName, environment.kernel())


def named_kernel(kernel: KernelName) -> KernelName:
    """The kernel a run asks for: ``kernel`` when it names one, else ``CRASHSTUDY_KERNEL``'s ("compiled": choose)."""
    return kernel if kernel != "compiled" else kernel_override()


def background_min_seconds() -> float:
    """Reference seconds of a run above which missing kernels compile in the background (inf: never).

    ``CRASHSTUDY_BACKGROUND_COMPILE``: ``0`` never, ``always`` for any run, unset or ``1`` above
    ``BACKGROUND_MIN`` (any other value is an input error: :mod:`crashstudy.environment`)."""
    return {"never": float("inf"), "always": 0.0}.get(environment.background_compile(), BACKGROUND_MIN)


def generated_compile_seconds(material: np.ndarray, n_walls: int, record: bool = False) -> float:
    """Expected seconds to compile one model shape's generated kernel: each ``general_nonlinear``
    spring (its loading/unloading/yield law inlined) costs most. Fit to the cold compiles of
    benchmarks/results/compile_costs.md (1 spring 2.6-5.5 s, helicopter 8.1 s, frontal 10.3 s), and growing with
    the square of the springs beyond a few dozen (compile_springs.md: 32 springs ~60 s, 64 ~200 s)."""
    general = int(np.sum(np.asarray(material) == GENERAL))
    S = len(material)
    return (
        GEN_BASE
        + GEN_GENERAL * general
        + GEN_SPRING * (S - general)
        + GEN_SPRING2 * max(S - GEN_SMALL, 0) ** 2
        + GEN_WALL * n_walls
        + GEN_RECORD * bool(record)
    )


def reference_seconds(n_steps: float, n_springs: int, element_steps: float) -> float:
    """Expected seconds of the NumPy reference for a batch whose longest variant has ``n_steps``."""
    return n_steps * (REF_STEP + REF_SPRING_STEP * n_springs) + element_steps * REF_ELEMENT_STEP


def _generic() -> Any:
    from crashstudy.kernel import compiled

    return compiled._run


def generic_ready() -> bool:
    """Whether the generic kernel is compiled (in this process or in numba's disk cache)."""
    return compiled_or_cached(_generic())


def generated_ready(
    b: Batch, histories: tuple[str, ...], vary: frozenset[int] | None, record: tuple[int, ...] = ()
) -> bool:
    from crashstudy.kernel import generated

    return generated.unsupported(b) is None and generated.is_compiled(b, histories, vary, record)


def compiling(folder: Path | None = None) -> bool:
    """Whether a process holds the compile lock of the kernel cache ``folder`` (default: this user's)."""
    folder = cache_dir() if folder is None else folder
    lock = folder / LOCK_NAME
    return why_not_private(folder) is None and lock.exists() and compile_lock.read_holder(lock) is not None


def own_compile_running() -> bool:
    """Whether a background compile this process started is still running (the run planned for it:
    :func:`decide`). A compile of another process never keeps a run on the reference (:func:`compile_foreground`)."""
    return any(proc.poll() is None for proc in _BACKGROUND)


def pick(
    b: Batch,
    histories: tuple[str, ...],
    vary: frozenset[int] | None,
    kernel: KernelName = "compiled",
    repeat: float = 1.0,
    record: tuple[int, ...] = (),
) -> KernelName:
    """The kernel for batch ``b``: ``kernel`` or ``CRASHSTUDY_KERNEL`` when either names one, else the
    one expected to finish the run first among those compiled and the reference; with nothing
    compiled, the kernel quicker to compile and run (this shape's generated one unless it is large or
    unsupported) compiled now only when the reference would take longer than that (whatever another
    process compiles: :func:`compile_foreground` waits for it or compiles beside it). ``repeat``: how many batches like ``b`` the run holds (loading a compiled kernel is
    paid once per process, so it is weighed against the whole run, not one chunk). ``record``: the
    batch needs the per-step acceleration of its metric nodes; only the kernels of ``RECORDING`` keep
    it, so another is never picked (not even when named: the criteria are never silently missing)."""
    from crashstudy.kernel import generated

    kernel = named_kernel(kernel)
    if record and kernel not in (*RECORDING, "compiled"):
        return "reference"
    if kernel == "generated" and generated.unsupported(b) is not None:
        return "generic"
    if kernel != "compiled":
        return kernel
    S = len(b.spring_i)
    work = float(np.sum(b.n_steps)) * max(S, 1) * max(repeat, 1.0)
    t_ref = reference_seconds(float(np.max(b.n_steps, initial=0)), S, float(np.sum(b.n_steps)) * max(S, 1))
    t_ref *= max(repeat, 1.0)

    def run_time(kind: str, rate: float) -> float:
        return work / rate + (0.0 if kind in _LOADED else LOAD)

    if t_ref <= LOAD and not _LOADED:  # nothing compiled can win once loading it is counted
        return "reference"
    usable = RECORDING if record else KERNELS
    times: dict[KernelName, float] = {"reference": t_ref}
    if "generated" in usable and generated_ready(b, histories, vary, record):
        times["generated"] = run_time("generated", GENERATED_RATE)
    if "generated" in times and times["generated"] <= run_time("generic", GENERIC_RATE):
        pass  # the generic kernel cannot win even if compiled: its module is not imported, its cache not looked at
    elif "generic" in usable and generic_ready():
        times["generic"] = run_time("generic", GENERIC_RATE)
    elif (
        "generic" in usable and len(times) == 1 and not own_compile_running()
    ):  # compile the quicker one here?
        ways: dict[KernelName, float] = {"generic": GENERIC_COMPILE + run_time("generic", GENERIC_RATE)}
        if "generated" in usable and generated.unsupported(b) is None:
            ways["generated"] = generated_compile_seconds(
                b.material, b.wall_nodes.shape[0], bool(record)
            ) + run_time("generated", GENERATED_RATE)
        first = min(ways, key=lambda k: ways[k])
        if t_ref > ways[first]:
            return first
    return min(times, key=lambda k: times[k])


def note_loaded(kernel: KernelName) -> None:
    """A compiled kernel of this kind was loaded in this process (no load time for it any more)."""
    _LOADED.add(kernel)


def plan_start(
    b: Batch,
    histories: tuple[str, ...],
    vary: frozenset[int] | None,
    n_variants: int,
    kernel: KernelName = "compiled",
    record: tuple[int, ...] = (),
    companion: Companion | None = None,
) -> StartPlan | None:
    """What a run of ``n_variants`` like ``b`` (a sample of them) is missing, or None (a kernel was
    named, everything is compiled, or the run is too short to care). ``record``: the metric nodes
    whose acceleration the kernels keep at every step (a generated kernel of its own); ``companion``:
    what the run compiles beside its kernel when it is missing (the crash criteria)."""
    from crashstudy.kernel import generated

    if named_kernel(kernel) != "compiled":
        return None
    S, (N, D, V) = len(b.spring_i), b.x0.shape
    per_variant = float(np.mean(b.n_steps)) if V else 0.0
    work = per_variant * max(S, 1) * n_variants
    chunks = -(-n_variants // REF_CHUNK)
    t_ref = reference_seconds(chunks * float(np.max(b.n_steps, initial=0)), S, work)
    t_generic = work / GENERIC_RATE + LOAD
    short = min(background_min_seconds(), BACKGROUND_MIN)  # [s] a run shorter than this compiles nothing
    if t_ref < short:
        return None  # short even on the NumPy reference: nothing is looked at, nothing written
    gen_ok = generated.unsupported(b) is None
    if gen_ok and generated.is_compiled(b, histories, vary, record):
        return None  # the fastest kernel is ready: the generic one is not looked at (nor its module imported)
    have_generic = generic_ready()
    if have_generic and t_generic < short:
        return None
    costs: dict[str, float] = {}
    if not have_generic:
        costs["generic"] = GENERIC_COMPILE
    if gen_ok:
        costs["generated"] = generated_compile_seconds(b.material, b.wall_nodes.shape[0], bool(record))
    if not costs:
        return None
    walls = b.wall_nodes.shape[0]
    shape = f"{N} nodes, {S} springs, {D}-D" + (f", {walls} wall{'s' * (walls > 1)}" if walls else "")
    t_fast = work / GENERATED_RATE + LOAD if gen_ok else t_generic
    if companion is not None and not companion.ready():
        return StartPlan(costs, t_ref, t_generic, t_fast, shape, companion.seconds, companion.name)
    return StartPlan(costs, t_ref, t_generic, t_fast, shape)


def start_background(
    kernels: tuple[str, ...],
    b: Batch,
    histories: tuple[str, ...],
    vary: frozenset[int] | None,
    record: tuple[int, ...] = (),
    must: bool = False,
    companion: Companion | None = None,
) -> subprocess.Popen[bytes] | None:
    """Compile ``kernels`` (or the ``companion`` alone, named in ``kernels``) in a detached low-priority process (it outlives this run, so the kernels
    are ready for the next one; a thread reaps it when it ends, so it never stays a zombie); None when
    no private cache folder is available. ``must``: a run waits for it (:func:`compile_foreground`), so it
    compiles even when another process holds the lock, at normal priority (a background one runs at
    nice 10: on a loaded machine a niced compile the run waited for took 3-4x its time)."""
    from crashstudy.kernel import generated

    folder = cache_dir()
    if why_not_private(folder) is not None:
        return None
    sample = b.take(np.arange(min(1, b.n_variants)))
    fd, npz = tempfile.mkstemp(prefix=".warm-", suffix=".npz", dir=folder)
    with os.fdopen(fd, "wb") as fh:
        np.savez(fh, **{k: v for k, v in vars(sample).items()})
    keys = [kernel_key(k, b, histories, vary, record) for k in kernels]
    job: dict[str, Any] = {
        "kernels": list(kernels),
        "histories": list(histories),
        "vary": sorted(vary or ()),
        "const": generated._constant_curves(b, vary),
        "npz": npz,
        "record": [int(n) for n in record],
        "keys": keys,
        "seconds": [compile_seconds(k, b, record, companion) for k in kernels],
        "must": must,
    }
    if companion is not None and kernels == (companion.name,):
        job |= {"lock": companion.lock, "call": companion.target}
    cmd = [sys.executable, "-m", "crashstudy.kernel.warm", json.dumps(job)]
    proc = subprocess.Popen(
        cmd,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
        preexec_fn=None if must else _lower_priority,
    )
    if not must:
        _BACKGROUND[:] = [p for p in _BACKGROUND if p.returncode is None] + [proc]
        threading.Thread(target=proc.wait, name=f"reap-{proc.pid}", daemon=True).start()
    return proc


def kernel_key(
    kernel: str,
    b: Batch,
    histories: tuple[str, ...],
    vary: frozenset[int] | None,
    record: tuple[int, ...] = (),
) -> str:
    """What a compile of ``kernel`` leaves in the cache, as a lock holder names it: "generic", a
    companion's name ("criteria"), or the generated kernel's shape key (one per model shape)."""
    if kernel != "generated":
        return kernel
    from crashstudy.kernel import generated

    return generated.shape_key(
        generated._shape(b, histories, vary, generated._constant_curves(b, vary), record)
    )


def compile_seconds(
    kernel: str, b: Batch, record: tuple[int, ...] = (), companion: Companion | None = None
) -> float:
    """Expected seconds to compile ``kernel`` ("generic", "generated" or the companion's name) for batch ``b``."""
    if kernel == "generated":
        return generated_compile_seconds(b.material, b.wall_nodes.shape[0], bool(record))
    return companion.seconds if companion is not None and kernel == companion.name else GENERIC_COMPILE


def _lower_priority() -> None:  # pragma: no cover - runs in the child
    os.nice(10)


def compile_foreground(
    kernels: tuple[str, ...],
    b: Batch,
    histories: tuple[str, ...],
    vary: frozenset[int] | None,
    stop: Any,
    record: tuple[int, ...] = (),
    say: Callable[[str], None] | None = None,
    companion: Companion | None = None,
) -> None:
    """Compile ``kernels`` in child processes and wait: the ``companion`` (the crash criteria, when
    ``kernels`` names it) in one of its own beside the others, so both cores compile; ``stop()`` raising
    (Ctrl-C) kills them at once.

    When another process holds the compile lock, wait for it only when it compiles what this run needs
    and is expected to finish sooner than compiling it here (:func:`crashstudy.kernel.compile_lock.plan_wait`;
    never longer than this run's own compile, not at all for a holder that is gone or stopped, and no
    more once it stops using CPU); else compile here beside it. ``say``: tells the terminal."""
    beside = companion.name if companion is not None else None
    groups = [
        g for g in (tuple(k for k in kernels if k == beside), tuple(k for k in kernels if k != beside)) if g
    ]
    procs: list[subprocess.Popen[bytes]] = []
    try:
        for group in groups:
            if _other_compiles(
                group, b, histories, vary, record, stop, say or (lambda text: None), companion
            ):
                continue
            proc = start_background(group, b, histories, vary, record, must=True, companion=companion)
            if proc is not None:
                procs.append(proc)
        for proc in procs:
            while proc.poll() is None:
                try:
                    proc.wait(timeout=0.2)
                except subprocess.TimeoutExpired:
                    stop()
    except BaseException:
        for proc in procs:
            proc.kill()
            proc.wait()
        raise


def _other_compiles(
    group: tuple[str, ...],
    b: Batch,
    histories: tuple[str, ...],
    vary: frozenset[int] | None,
    record: tuple[int, ...],
    stop: Any,
    say: Callable[[str], None],
    companion: Companion | None = None,
) -> bool:
    """Whether another process compiled ``group`` while this run waited for it (see :func:`compile_foreground`)."""
    alone = companion is not None and group == (companion.name,)
    lock = cache_dir() / (companion.lock if companion is not None and alone else LOCK_NAME)
    holder = compile_lock.read_holder(lock)
    if holder is None:
        return False
    what = (
        companion.label if companion is not None and alone else " and ".join(f"the {k} kernel" for k in group)
    )
    own = sum(compile_seconds(k, b, record, companion) for k in group)
    key = kernel_key(group[-1], b, histories, vary, record)
    limit, why = compile_lock.plan_wait(holder, key, own)
    if limit <= 0:
        say(f"compiling {what} here (~{own:.0f} s) beside another compile: {why}")
        return False
    say(f"waiting for {what}: {why}; compiling it here would take ~{own:.0f} s")

    def ready() -> bool:
        return all(_ready(k, b, histories, vary, record, companion) for k in group)

    end = compile_lock.wait(lock, holder, limit, ready, stop, key)
    if end == "ready":
        return True
    because = {
        "released": "the lock was released without it",
        "gone": "the holder is gone",
        "stopped": "the holder is stopped",
        "stuck": "the holder uses no CPU",
        "slow": "at the CPU share it gets, the holder would finish later than compiling here",
        "limit": "it takes longer than expected",
    }[end]
    say(f"stopped waiting ({because}); compiling {what} here (~{own:.0f} s)")
    return False


def _ready(
    kernel: str,
    b: Batch,
    histories: tuple[str, ...],
    vary: frozenset[int] | None,
    record: tuple[int, ...],
    companion: Companion | None = None,
) -> bool:
    if kernel == "generic":
        return generic_ready()
    if companion is not None and kernel == companion.name:
        return companion.ready()
    return generated_ready(b, histories, vary, record)
