"""The pipeline, end to end: study/model file -> plan -> chunks on a backend -> result files.

This is the one module that knows every stage; the command line only parses arguments, prints and
sets exit codes. Each chunk is computed by :func:`run_chunk`, a pure function of the plan and a
variant range, so any backend (in-process, process pool, Dask) gives identical results.
"""

from __future__ import annotations

import os
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crashstudy import interrupt
from crashstudy.batch import INVALID_REASONS, Batch, build_batch
from crashstudy.errors import InputError, Problem
from crashstudy.kernel.output import CRUSHED_TO_ZERO, INVALID, UNSTABLE, KernelOutput, allocate
from crashstudy.provenance import variant_hashes
from crashstudy.results import FINAL, PARTIAL, ChunkResult, Results, ResultWriter
from crashstudy.safefs import clear_entry
from crashstudy.schema import load_model
from crashstudy.study import Plan, load_study, plan_from_model

HISTORY_BUDGET = 256 * 2**20  # bytes of history arrays per chunk
MAX_CHUNK = 8192  # variants per chunk when histories are small or off


def chunk_size(plan: Plan) -> int:
    """Variants per chunk: bounded so that a chunk's history arrays stay within HISTORY_BUDGET."""
    topo = plan.topology
    per = {"node": topo.n_nodes * topo.dim, "spring": topo.n_springs, "wall": len(topo.wall_ids)}
    from crashstudy.kernel.output import HISTORY_SHAPES

    width = sum(per[HISTORY_SHAPES[h][0]] if HISTORY_SHAPES[h] else 1 for h in topo.histories)
    per_variant = 8 * plan.n_out * (width + 4)  # + the kernel's energy buffer
    return int(max(1, min(MAX_CHUNK, HISTORY_BUDGET // max(per_variant, 1))))


GENERATED_MIN_WORK = 5e9  # element-steps of a run above which compiling the model's own kernel pays (~10 s
# of compilation against ~3.5e8 vs ~1e9 element-steps/s of the generic and generated kernels)


def run_kernel(batch: Batch, histories: tuple[str, ...], n_out: int, kernel: str = "compiled",
               work: float = 0.0, vary: frozenset[int] | None = None) -> KernelOutput:  # fmt: skip
    """Integrate ``batch`` with ``kernel``: "compiled" (the model's generated kernel when it supports the
    model and is already compiled or the run's ``work`` [element-steps] earns its compilation back,
    else the generic one), "generic", "generated" or "reference" (NumPy; tests). ``vary``: indices
    of the curves the study varies (see :func:`varying_curves`). The environment variable
    ``CRASHSTUDY_KERNEL`` (generic / generated) overrides "compiled" (docs/kernels.md)."""
    if kernel == "compiled":  # the environment may choose; a generated kernel only where it applies
        kernel = kernel_override()
        if kernel == "generated" and _generated().unsupported(batch) is not None:
            kernel = "generic"
    if kernel == "reference":
        from crashstudy.kernel.reference import run_reference

        return run_reference(batch, histories, n_out)
    generated = _generated()
    if kernel == "generated" or (
        kernel == "compiled"
        and generated.unsupported(batch) is None
        and (work >= GENERATED_MIN_WORK or generated.is_compiled(batch, histories, vary))
    ):
        return generated.run_generated(batch, histories, n_out, vary)
    from crashstudy.kernel.compiled import run_compiled

    return run_compiled(batch, histories, n_out)


def _generated() -> Any:
    from crashstudy.kernel import generated

    return generated


def kernel_override() -> str:
    """The kernel ``CRASHSTUDY_KERNEL`` asks for ("compiled" = choose; "generic", "generated")."""
    value = os.environ.get("CRASHSTUDY_KERNEL", "").strip() or "compiled"
    if value not in ("compiled", "generic", "generated"):
        raise InputError([Problem("environment", None, "CRASHSTUDY_KERNEL",
                                  f"unknown kernel {value!r}: expected generic or generated (or unset)")])  # fmt: skip
    return value


def varying_curves(plan: Plan) -> frozenset[int]:
    """Indices of the curves a study's axes change (``curves.<id>...`` paths)."""
    ids = plan.topology.curve_ids
    names = {ax.path.split(".")[1] for ax in plan.axes if ax.path.startswith("curves.")}
    return frozenset(ids.index(c) for c in names if c in ids)


def _reorder(out: KernelOutput, take: np.ndarray, V: int, histories: tuple[str, ...], n_out: int,
             S: int, N: int, D: int, W: int) -> KernelOutput:  # fmt: skip
    """Spread results computed for columns ``take`` (unique, sorted) back to all ``V`` variants."""
    full = allocate(S, N, D, W, V, histories, n_out)
    for name in ("status", "fail_time", "fail_item", "t_end", "peak_force", "max_crush", "absorbed_energy",
                 "peak_acceleration", "peak_wall_force", "energy_error", "final_energy"):  # fmt: skip
        getattr(full, name)[...] = getattr(out, name)[..., take]
    for h in histories:
        full.histories[h][...] = out.histories[h][..., take]
    return full


def run_chunk(plan: Plan, lo: int, hi: int, kernel: str = "compiled") -> ChunkResult:
    """Compute variants ``lo`` .. ``hi - 1`` of ``plan``.

    Identical variants are computed once; the rest are ordered by step count so that the kernel's
    blocks hold variants that finish together.
    """
    topo = plan.topology
    P = plan.params(lo, hi)
    V = hi - lo
    # a variant's parameters are a function of its axis values: dedupe on those (few columns)
    axes = plan.axis_values(lo, hi)
    if axes:
        _, first, inverse = np.unique(np.stack(list(axes.values()), axis=1), axis=0, return_index=True,
                                      return_inverse=True)  # fmt: skip
        uniq = P[:, first]
    else:
        uniq, inverse = P[:, :1], np.zeros(V, dtype=np.int64)
    inverse = inverse.reshape(-1)
    batch, steps = build_batch(topo, np.ascontiguousarray(uniq), plan.interval)
    order = np.argsort(batch.n_steps, kind="stable")
    sorted_batch = batch.take(order)
    work = float(np.sum(batch.n_steps)) * topo.n_springs * plan.n_variants / max(batch.n_variants, 1)
    out = run_kernel(sorted_batch, topo.histories, plan.n_out, kernel, work, varying_curves(plan))
    estimate = error_estimate(sorted_batch, out, kernel) if topo.accuracy_check else np.full(len(order), np.nan)
    pos = np.empty_like(order)
    pos[order] = np.arange(len(order))
    N, D, S, W = topo.n_nodes, topo.dim, topo.n_springs, len(topo.wall_ids)
    full = _reorder(out, pos[inverse], V, topo.histories, plan.n_out, S, N, D, W)
    dt, dt_crit = steps.dt[inverse], steps.dt_crit[inverse]
    ctrl_n, ctrl_s = steps.control_node[inverse], steps.control_spring[inverse]
    control = [
        ("none" if n < 0 else f"node {topo.node_ids[n]}") + (f" / spring {topo.spring_ids[s]}" if s >= 0 else "")
        for n, s in zip(ctrl_n, ctrl_s, strict=True)
    ]
    user_dt = P[topo.blocks["time_step"].start]
    reasons = [_reason(full, k, topo.spring_ids, user_dt[k], dt_crit[k], control[k]) for k in range(V)]
    return ChunkResult(np.arange(lo, hi), full, dt, dt_crit, control, reasons, variant_hashes(plan, P),
                       estimate[pos[inverse]])  # fmt: skip


def error_estimate(batch: Batch, out: KernelOutput, kernel: str = "compiled") -> np.ndarray:
    """Richardson estimate of the relative error of the reported peaks, per variant.

    The variants are run again at half the step; for a second-order method the error of a value
    ``X_h`` is about ``(X_h - X_{h/2}) * 4/3``. The estimate is the largest relative error over the
    peak forces and peak decelerations (items below 1e-9 of the variant's largest value of that kind
    are left out). Absorbed energy is not included: for an elastic spring it is the energy stored at
    the end time, a phase-sensitive value whose relative error says little about the peaks.
    """
    import dataclasses

    half = dataclasses.replace(batch, dt=batch.dt / 2, n_steps=batch.n_steps * 2, out_every=batch.out_every * 2)
    fine = run_kernel(half, (), 1, kernel, float(np.sum(half.n_steps)) * len(batch.spring_i))
    worst = np.zeros(batch.n_variants)
    for name in ("peak_force", "peak_acceleration"):
        coarse, ref = getattr(out, name), getattr(fine, name)
        scale = np.max(np.abs(ref), axis=0, initial=0.0)
        keep = np.abs(ref) > 1e-9 * scale
        rel = np.divide(np.abs(coarse - ref) * 4.0 / 3.0, np.abs(ref), out=np.zeros_like(ref), where=keep)
        worst = np.maximum(worst, np.max(rel, axis=0, initial=0.0))
    return np.where((out.status == 0) & (fine.status == 0), worst, np.nan)


def _reason(out: KernelOutput, k: int, springs: tuple[str, ...], user_dt: float, dt_crit: float, control: str) -> str:
    code = int(out.status[k])
    t = out.fail_time[k]
    if code == UNSTABLE:
        return (f"numerical instability: energy balance lost (non-finite, or error above 100%) at t={t:.6g} "
                f"(dt_crit={dt_crit:.6g}, {control})")  # fmt: skip
    if code == CRUSHED_TO_ZERO:
        return f"spring {springs[int(out.fail_item[k])]!r} crushed to zero length at t={t:.6g}"
    if code == INVALID:
        item = int(out.fail_item[k])
        if item == 1:
            return f"fixed dt={user_dt:.6g} is above the critical step dt_crit={dt_crit:.6g} ({control})"
        return f"invalid input: {INVALID_REASONS.get(item, 'unknown')}"
    return ""


class Progress:
    """One status line on a terminal (variants done, variants/s, ETA); silent otherwise."""

    def __init__(self, total: int, enabled: bool | None = None, stream: Any = None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty() if enabled is None else enabled
        self.total, self.done, self.t0, self.last = total, 0, time.perf_counter(), 0.0

    def update(self, n: int) -> None:
        self.done += n
        now = time.perf_counter()
        if not self.enabled or (now - self.last < 0.2 and self.done < self.total):
            return
        self.last = now
        rate = self.done / max(now - self.t0, 1e-9)
        eta = (self.total - self.done) / rate if rate > 0 else float("inf")
        self.stream.write(f"\r  {self.done}/{self.total} variants  {rate:,.0f} variants/s  ETA {eta:,.0f} s   ")
        self.stream.flush()

    def close(self) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()


@dataclass
class RunReport:
    """What a run did: where the results are and how many variants failed."""

    results: Results
    n_variants: int
    n_failed: int
    n_computed: int
    seconds: float
    n_reused: int = 0


def _ranges(todo: np.ndarray, size: int) -> list[tuple[int, int]]:
    """Contiguous ranges of the variants still to do, each at most ``size`` long."""
    out: list[tuple[int, int]] = []
    idx = np.nonzero(todo)[0]
    if not len(idx):
        return out
    breaks = np.nonzero(np.diff(idx) != 1)[0] + 1
    for run in np.split(idx, breaks):
        for lo in range(int(run[0]), int(run[-1]) + 1, size):
            out.append((lo, min(lo + size, int(run[-1]) + 1)))
    return out


def prepare_output(out_dir: Path, resume: bool, force: bool, source: str, study_name: str) -> None:
    """Refuse to overwrite another study's results or an unfinished run unless ``force``; clear when forced.

    A finished result of the *same* study is not refused: the run reuses its unchanged variants.
    """
    final, partial = out_dir / FINAL, out_dir / PARTIAL
    if out_dir.exists() and not out_dir.is_dir():
        raise InputError([Problem(source, None, "", f"the output path {out_dir} is a file, not a folder")])
    if force and out_dir.exists():
        for p in (final, partial, out_dir / "summary.csv"):
            clear_entry(p)  # a link is removed, never followed (a dangling one too)
        return
    if final.exists() and not resume:
        other = _study_of(final)
        if other != study_name:
            raise InputError([Problem(source, None, "", f"{out_dir} holds the results of {other!r}, not of study "
                                      f"{study_name!r}; use --force to overwrite or choose another -o")])  # fmt: skip
    if os.path.lexists(partial) and not resume:
        raise InputError([Problem(source, None, "", f"an unfinished run is in {out_dir}; use --resume to finish it or --force to start again")])


def _study_of(final: Path) -> str:
    import netCDF4

    try:
        with netCDF4.Dataset(final) as nc:
            return str(nc.getncattr("study_name")) if "study_name" in nc.ncattrs() else "an unknown study"
    except OSError:
        return "an unreadable file"


def _reuse_finished(writer: ResultWriter, plan: Plan, final: Path, size: int) -> int:
    """Copy the variants of an earlier result of this study whose input hash is unchanged."""
    import netCDF4

    from crashstudy.provenance import topology_signature

    with netCDF4.Dataset(final) as old:
        if "input_hash" not in old.variables:
            return 0
        old_hashes = {h: k for k, h in reversed(list(enumerate(old.variables["input_hash"][:])))}
        sig = topology_signature(plan)
        new_idx: list[int] = []
        old_idx: list[int] = []
        for lo in range(0, plan.n_variants, size):
            hi = min(plan.n_variants, lo + size)
            for k, h in enumerate(variant_hashes(plan, plan.params(lo, hi), sig)):
                if h in old_hashes:
                    new_idx.append(lo + k)
                    old_idx.append(old_hashes[h])
        writer.reuse(old, np.asarray(new_idx, dtype=np.int64), np.asarray(old_idx, dtype=np.int64))
    return len(new_idx)


def run_plan(plan: Plan, out_dir: str | os.PathLike[str], jobs: int = 1, scheduler: str | None = None,
             resume: bool = False, force: bool = False, progress: bool | None = None,
             kernel: str = "compiled", chunk: int | None = None) -> RunReport:  # fmt: skip
    """Run every variant of ``plan`` into ``out_dir`` (see :func:`run_study`)."""
    from crashstudy.backends import make_backend

    t0 = time.perf_counter()
    out = Path(out_dir)
    kernel_override()  # a bad CRASHSTUDY_KERNEL is an input error before anything is written
    prepare_output(out, resume, force, plan.study_file or plan.model_file, plan.name)
    if resume and (out / FINAL).exists() and not os.path.lexists(out / PARTIAL):
        # nothing to resume: the run finished. Run it again like a plain re-run of the same study (its
        # unchanged variants are reused by input hash, changed ones computed); another study is refused
        other = _study_of(out / FINAL)
        if other != plan.name:
            raise InputError([Problem(plan.study_file or plan.model_file, None, "",
                                      f"{out} holds the finished results of {other!r}, not of study {plan.name!r}: "
                                      "nothing to resume; use --force to overwrite or choose another -o")])  # fmt: skip
        resume = False
    backend = make_backend(jobs, scheduler)  # before any file is written: a backend that cannot start leaves none
    try:
        writer = ResultWriter(out, plan, resume=resume)
    except BaseException:
        backend.close()
        raise
    reused = 0
    n_failed = 0
    bar = Progress(plan.n_variants, progress)
    try:
        if not resume and (out / FINAL).exists():
            reused = _reuse_finished(writer, plan, out / FINAL, chunk or MAX_CHUNK)
        todo = ~writer.done()
        size = chunk or chunk_size(plan)
        if chunk is None and (scheduler or jobs > 1):  # several chunks per worker thread keep every worker busy
            slots = backend.worker_threads() if hasattr(backend, "worker_threads") else jobs
            size = min(size, max(1, -(-int(todo.sum()) // (4 * max(1, slots)))))
        ranges = _ranges(todo, size)
        bar.update(int((~todo).sum()))
        for res in backend.imap_unordered(run_chunk, ((plan, lo, hi, kernel) for lo, hi in ranges)):
            writer.write(res)
            n_failed += int(np.count_nonzero(res.out.status))
            bar.update(len(res.index))
            interrupt.check()  # a signal's stop request: after a whole chunk is written
    except BaseException:
        writer.abort()
        backend.close()
        bar.close()
        raise
    backend.close()
    bar.close()
    writer.finish()
    results = Results(out)
    if resume or reused:
        n_failed = int((results.summary["status"] != "ok").sum())
    return RunReport(results, plan.n_variants, n_failed, int(todo.sum()), time.perf_counter() - t0, reused)


def default_out(name: str) -> Path:
    return Path("results") / name


def run_study(study: str | os.PathLike[str] | dict[str, Any], out_dir: str | os.PathLike[str] | None = None,
              jobs: int = 1, scheduler: str | None = None, resume: bool = False, force: bool = False,
              progress: bool | None = False) -> Results:  # fmt: skip
    """Run a study (a file path or a dict as its YAML would load) and return its :class:`Results`.

    Results go to ``out_dir`` (default ``results/<study name>``). Raises
    :class:`~crashstudy.errors.InputError` for invalid input. Failed variants are marked in the
    results (``status``, ``failure_reason``), never raised.
    """
    plan = load_study(study)
    return run_plan(plan, out_dir or default_out(plan.name), jobs, scheduler, resume, force, progress).results


def simulate(model: str | os.PathLike[str], out_dir: str | os.PathLike[str] | None = None,
             force: bool = True) -> Results:  # fmt: skip
    """Run one model file (no matrix) and return its :class:`Results` (a ``variant`` dim of length 1)."""
    report = simulate_report(str(model), out_dir, force)
    return report.results


def simulate_report(model: str, out_dir: str | os.PathLike[str] | None = None, force: bool = True) -> RunReport:
    lm = load_model(model)
    plan = plan_from_model(lm)
    refuse_fixed_dt(plan, lm.doc)
    out = Path(out_dir) if out_dir else default_out(plan.name)
    return run_plan(plan, out, force=force, progress=False)


def refuse_fixed_dt(plan: Plan, doc: Any) -> None:
    """A single model with a fixed ``dt`` above the critical step is invalid input (exit 2)."""
    if plan.topology.time_step_mode != "dt":
        return
    batch, steps = build_batch(plan.topology, plan.params(0, 1), plan.interval)
    if steps.refused[0]:
        n, s = int(steps.control_node[0]), int(steps.control_spring[0])
        ctrl = f"node {plan.topology.node_ids[n]}" + (f", spring {plan.topology.spring_ids[s]}" if s >= 0 else "")
        dt = plan.base[plan.topology.blocks["time_step"].start]
        raise InputError([Problem(doc.file, doc.line_of(("time_step", "dt")), "time_step.dt",
                                  f"dt={dt:.6g} is above the critical step dt_crit={steps.dt_crit[0]:.6g} "
                                  f"(controlled by {ctrl}); use a smaller dt or safety_factor")])  # fmt: skip


def remove_tree(path: Path) -> None:
    shutil.rmtree(path, ignore_errors=True)
