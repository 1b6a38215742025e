"""The pipeline, end to end: study/model file -> plan -> chunks on a backend -> result files.

This is the one module that knows every stage; the command line only parses arguments, prints and
sets exit codes. Each chunk is computed by :func:`crashstudy.run.chunk.run_chunk`, a pure function of the
plan and a variant range, so any backend (in-process, process pool, Dask) gives identical results.
"""

from __future__ import annotations

import contextlib
import functools
import os
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from crashstudy import interrupt
from crashstudy.arrays.batch import Batch, build_batch
from crashstudy.errors import InputError, Problem
from crashstudy.kernel import choice, entry
from crashstudy.kernel.output import KernelOutput
from crashstudy.run.chunk import run_chunk
from crashstudy.run.progress import Progress
from crashstudy.run.start import start_kernels
from crashstudy.run.write_behind import WriteBehind
from crashstudy.safefs import FolderBusy, folder_lock
from crashstudy.study.plan import Plan, load_study, plan_from_model
from crashstudy.vocabulary.codes import KernelName

if TYPE_CHECKING:  # the writer (netCDF4) and reader (pandas, xarray) are imported by the functions that
    # write: a --jobs worker unpickles run_chunk from this module and needs neither
    from crashstudy.results.store import Results, ResultWriter

HISTORY_BUDGET = 256 * 2**20  # bytes of history arrays per chunk
MAX_CHUNK = 65536  # variants per chunk at most
BASE_CHUNK = 8192  # variants per chunk of a model with long runs (when histories allow)
WORK_PER_CHUNK = 2e8  # element-steps above which a chunk stops growing past BASE_CHUNK (~0.2 s compiled)


def chunk_size(plan: Plan) -> int:
    """Variants per chunk: BASE_CHUNK, more (up to MAX_CHUNK) for variants of little work so that the
    per-chunk costs (kernel launch, file writes) spread over more of them; bounded so that a chunk's
    history arrays stay within HISTORY_BUDGET."""
    topo = plan.topology
    sample, _ = build_batch(topo, plan.params(0, min(plan.n_variants, 16)), plan.interval)
    work = float(np.mean(sample.n_steps)) * max(topo.n_springs, 1)
    by_work = max(BASE_CHUNK, int(WORK_PER_CHUNK / max(work, 1.0)))
    per = {"node": topo.n_nodes * topo.dim, "spring": topo.n_springs, "wall": len(topo.wall_ids)}
    from crashstudy.kernel.output import ALL_SHAPES

    width = sum(per[ALL_SHAPES[h][0]] if ALL_SHAPES[h] else 1 for h in topo.histories + topo.extra_histories)
    per_variant = 8 * plan.n_out * (width + 4)  # + the kernel's energy buffer
    # the per-step record of the metric nodes (crashstudy.metrics.record runs a bigger chunk in several batches)
    record = 8 * (float(np.max(sample.n_steps, initial=0)) + 1) * len(topo.metric_nodes) * topo.dim
    return int(
        max(
            1,
            min(
                MAX_CHUNK, by_work, HISTORY_BUDGET // max(per_variant, 1), HISTORY_BUDGET // max(record, 1.0)
            ),
        )
    )


def run_kernel(
    batch: Batch,
    histories: tuple[str, ...],
    n_out: int,
    kernel: KernelName = "compiled",
    vary: frozenset[int] | None = None,
    repeat: float = 1.0,
) -> KernelOutput:
    """:func:`crashstudy.kernel.entry.run_batch`, abandoned at a stop request (Ctrl-C)."""
    return entry.run_batch(batch, histories, n_out, kernel, vary, repeat, interrupt.check)


def error_estimate(
    batch: Batch, out: KernelOutput, kernel: KernelName = "compiled", repeat: float = 1.0
) -> np.ndarray:
    """:func:`crashstudy.kernel.entry.error_estimate`, abandoned at a stop request (Ctrl-C)."""
    return entry.error_estimate(batch, out, kernel, repeat, interrupt.check)


kernel_override = choice.kernel_override
__all__ = [
    "output_folder",
    "run_chunk",
    "run_plan",
    "run_study",
    "simulate",
]


@dataclass
class RunReport:
    """What a run did: where the results are and how many variants failed."""

    results: Results
    n_variants: int
    n_failed: int
    n_computed: int
    seconds: float
    n_reused: int = 0


def run_plan(
    plan: Plan,
    out_dir: str | os.PathLike[str],
    jobs: int = 1,
    scheduler: str | None = None,
    resume: bool = False,
    force: bool = False,
    progress: bool | None = None,
    kernel: KernelName = "compiled",
    chunk: int | None = None,
    notes: Any = None,
    csv: bool | None = None,
    locked: bool = False,
    store: str | None = None,
) -> RunReport:
    """Run every variant of ``plan`` into ``out_dir`` (see :func:`run_study`). ``notes``: a stream for
    one-line notes (a kernel compiling), e.g. ``sys.stderr``; None: silent. ``csv``: write
    ``summary.csv`` (None: up to ``results.CSV_MAX`` variants); ``summary.parquet`` is always written."""
    t0 = time.perf_counter()
    out = Path(out_dir)
    choice.kernel_override()  # a bad CRASHSTUDY_KERNEL is an input error before anything is written
    source = plan.study_file or plan.model_file
    if out.exists() and not out.is_dir():
        raise InputError([Problem(source, None, "", f"the output path {out} is a file, not a folder")])
    if locked:  # the caller holds the folder's lock (optimize, calibrate: over their whole search)
        return _run_locked(
            plan, out, jobs, scheduler, resume, force, progress, kernel, chunk, notes, csv, t0, store
        )
    with output_folder(out, source):  # one run at a time in a folder: held until the run ends
        return _run_locked(
            plan, out, jobs, scheduler, resume, force, progress, kernel, chunk, notes, csv, t0, store
        )


@contextlib.contextmanager
def output_folder(out: Path, source: str) -> Iterator[None]:
    """Hold the lock of the output folder ``out`` (created if missing) while the block runs; another
    process holding it is an input error naming ``source``."""
    try:
        with folder_lock(out):
            yield
    except FolderBusy as exc:  # raised only by the lock
        raise InputError(
            [Problem(source, None, "", f"{exc}; wait for it to end or choose another -o")]
        ) from None


def _run_locked(
    plan: Plan,
    out: Path,
    jobs: int,
    scheduler: str | None,
    resume: bool,
    force: bool,
    progress: bool | None,
    kernel: KernelName,
    chunk: int | None,
    notes: Any,
    csv: bool | None,
    t0: float,
    store: str | None = None,
) -> RunReport:
    """:func:`run_plan` once the output folder is locked."""
    from crashstudy.results import integrity
    from crashstudy.results.outdir import prepare_output, study_of
    from crashstudy.results.regions import region_tasks
    from crashstudy.results.store import FINAL, Results, ResultWriter
    from crashstudy.results.zarr_file import ZARR_FINAL, ZARR_PARTIAL, variant_chunk
    from crashstudy.run.backends import make_backend
    from crashstudy.run.reuse import _ranges, _reuse_finished

    prepare_output(out, resume, force, plan.study_file or plan.model_file, plan.name)
    if store is None:  # the folder's kind of store is kept (--resume continues it); a new folder: netCDF
        store = "zarr" if any(os.path.lexists(out / n) for n in (ZARR_PARTIAL, ZARR_FINAL)) else "netcdf"
    final = out / integrity.final_name(out)
    partial = out / integrity.partial_name(ZARR_FINAL if store == "zarr" else FINAL)
    if resume and final.exists() and not os.path.lexists(partial):
        # nothing to resume: the run finished. Run it again like a plain re-run of the same study (its
        # unchanged variants are reused by input hash, changed ones computed); another study is refused
        other = study_of(final)
        if other != plan.name:
            raise InputError(
                [
                    Problem(
                        plan.study_file or plan.model_file,
                        None,
                        "",
                        f"{out} holds the finished results of {other!r}, not of study {plan.name!r}: "
                        "nothing to resume; use --force to overwrite or choose another -o",
                    )
                ]
            )
        resume = False
    backend = make_backend(
        jobs, scheduler
    )  # before any file is written: a backend that cannot start leaves none
    size = chunk or chunk_size(plan)
    slots = backend.worker_threads() if hasattr(backend, "worker_threads") else jobs
    if chunk is None and (scheduler or jobs > 1):  # several chunks per worker thread keep every worker busy
        size = min(size, max(1, -(-plan.n_variants // (4 * max(1, slots)))))
    if (
        store == "zarr" and resume
    ):  # the chunks of the unfinished store: each computed chunk is one stored object
        size = variant_chunk(partial) or size
    make = functools.partial(ResultWriter, out, plan, resume=resume, csv=csv, store=store, chunk=size)
    # a fresh run (nothing to resume or reuse, no worker writing the store) creates the store on the writer
    # thread while the kernels start and the first chunk computes (the store's template: ~0.3 s at 10^6)
    fresh = not resume and not final.exists() and not (scheduler and store == "zarr")
    behind = WriteBehind(lambda res: made.result().write(res))
    try:
        made = behind.call(make) if fresh else _done(make)
    except BaseException:
        behind.stop()
        backend.close()
        raise
    reused = 0
    n_failed = 0
    bar = Progress(plan.n_variants, progress)
    try:
        small, bar.estimate, later = start_kernels(plan, kernel, notes)
        if not fresh and final.exists():
            reused = _reuse_finished(made.result(), plan, final, chunk or MAX_CHUNK)
        todo = np.ones(plan.n_variants, dtype=bool) if fresh else ~made.result().done()
        if chunk is None and (scheduler or jobs > 1) and store != "zarr":  # of what is left (resume, reuse)
            size = min(size, max(1, -(-int(todo.sum()) // (4 * max(1, slots)))))
        if small:
            size = min(size, choice.REF_CHUNK)
        ranges = _ranges(todo, size)
        bar.start(int((~todo).sum()))
        compute: Any = run_chunk
        tasks: Iterator[tuple[Any, ...]] = ((plan, lo, hi, kernel) for lo, hi in ranges)
        if scheduler and store == "zarr":  # the workers write their regions of the store (results/regions.py)
            compute, tasks = region_tasks(made.result(), run_chunk, plan, ranges, kernel)
        written = 0  # variants of the chunk being written: shown once its write has ended
        for res in backend.imap_unordered(compute, tasks):
            behind.put(
                res
            )  # written on the writer thread while the next chunk computes (the previous one ended)
            bar.update(
                written
            )  # the line counts written variants only (a kill after it finds them in the file)
            written = res.size
            n_failed += res.n_failed
            interrupt.check()  # a signal's stop request: after a whole chunk is handed over (and then written)
        behind.close()
        bar.update(written)
    except BaseException:
        behind.stop()  # the write under way ends first: the partial file stays whole for --resume
        if made.done() and made.exception() is None:
            made.result().abort()
        backend.close()
        bar.close()
        raise
    backend.close()
    bar.close()
    made.result().finish()
    if later is not None:
        later()
    results = Results(out)
    if resume or reused:
        n_failed = results.count_failed()
    return RunReport(results, plan.n_variants, n_failed, int(todo.sum()), time.perf_counter() - t0, reused)


def _done(make: Callable[[], ResultWriter]) -> Future[ResultWriter]:
    """``make()`` called now, as a finished future (its error raised here)."""
    done: Future[ResultWriter] = Future()
    done.set_result(make())
    return done


def default_out(name: str) -> Path:
    return Path("results") / name


def run_study(
    study: str | os.PathLike[str] | dict[str, Any],
    out_dir: str | os.PathLike[str] | None = None,
    jobs: int = 1,
    scheduler: str | None = None,
    resume: bool = False,
    force: bool = False,
    progress: bool | None = False,
) -> Results:
    """Run a study (a file path or a dict as its YAML would load) and return its :class:`Results`.

    Results go to ``out_dir`` (default ``results/<study name>``). Raises
    :class:`~crashstudy.errors.InputError` for invalid input. Failed variants are marked in the
    results (``status``, ``failure_reason``), never raised.
    """
    plan = load_study(study)
    return run_plan(plan, out_dir or default_out(plan.name), jobs, scheduler, resume, force, progress).results


def simulate(
    model: str | os.PathLike[str], out_dir: str | os.PathLike[str] | None = None, force: bool = True
) -> Results:
    """Run one model file (no matrix) and return its :class:`Results` (a ``variant`` dim of length 1)."""
    report = simulate_report(str(model), out_dir, force)
    return report.results


def simulate_report(
    model: str,
    out_dir: str | os.PathLike[str] | None = None,
    force: bool = True,
    notes: Any = None,
    warn: Callable[[str], None] | None = None,
) -> RunReport:
    """Run one model file; ``force=False`` refuses a folder holding other results (the command line's
    default). ``warn`` receives the plausibility warnings of the model before it runs."""
    from crashstudy.schema import file_kind, parse_model
    from crashstudy.schema.yamlio import load_yaml

    doc = load_yaml(model)
    if file_kind(doc.data) == "study":
        raise InputError(
            [
                Problem(
                    model,
                    None,
                    "",
                    f"this is a study, not a model (it has "
                    f"{', '.join(k for k in doc.data if k in ('model', 'matrix', 'zip', 'set'))}): "
                    f"run its variants with `crashstudy run {model}`",
                )
            ]
        )
    lm = parse_model(doc)
    plan = plan_from_model(lm)
    refuse_fixed_dt(plan, lm.doc)
    if warn is not None:
        from crashstudy.study.sanity import check_plan

        for line in check_plan(plan)[1]:
            warn(line)
    out = Path(out_dir) if out_dir else default_out(plan.name)
    return run_plan(plan, out, force=force, progress=False, notes=notes)


def refuse_fixed_dt(plan: Plan, doc: Any) -> None:
    """A single model with a fixed ``dt`` above the critical step is invalid input (exit 2)."""
    if plan.topology.time_step_mode != "dt":
        return
    batch, steps = build_batch(plan.topology, plan.params(0, 1), plan.interval)
    if steps.refused[0]:
        n, s = int(steps.control_node[0]), int(steps.control_spring[0])
        ctrl = f"node {plan.topology.node_ids[n]}" + (
            f", spring {plan.topology.spring_ids[s]}" if s >= 0 else ""
        )
        dt = plan.base[plan.topology.blocks["time_step"].start]
        raise InputError(
            [
                Problem(
                    doc.file,
                    doc.line_of(("time_step", "dt")),
                    "time_step.dt",
                    f"dt={dt:.6g} is above the critical step dt_crit={steps.dt_crit[0]:.6g} "
                    f"(controlled by {ctrl}); use a smaller dt or safety_factor",
                )
            ]
        )
