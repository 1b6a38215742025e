"""The kernels a run starts with: carries out :func:`crashstudy.kernel.decision.decide` (compile in the
foreground, in the background, or run on the NumPy reference first) and says so on the notes stream."""

from __future__ import annotations

from typing import Any

from crashstudy import interrupt
from crashstudy.arrays.batch import build_batch
from crashstudy.kernel import choice
from crashstudy.kernel.decision import decide
from crashstudy.study.plan import Plan
from crashstudy.vocabulary.codes import KernelName


def start_kernels(plan: Plan, kernel: KernelName, notes: Any) -> tuple[bool, float | None, Any]:
    """Carry out :func:`crashstudy.kernel.decision.decide` for this run and say what it compiles.
    Returns (whether chunks should stay small, the run's estimated seconds, what to start after it)."""
    topo = plan.topology
    sample, _ = build_batch(topo, plan.params(0, min(plan.n_variants, 64)), plan.interval)
    vary = plan.varying_curves
    rec = (
        topo.metric_nodes
    )  # metrics: the kernels record these nodes at every step (their own generated kernel)
    from crashstudy.metrics.warmup import CRITERIA

    companion = CRITERIA if rec else None  # the crash criteria compile beside the kernel
    if choice.named_kernel(kernel) == "generated" and notes is not None:
        from crashstudy.kernel import generated

        why = generated.unsupported(sample)
        if why is not None:
            print(f"note: the generic kernel runs this model, not the generated one: {why}", file=notes)
    start = choice.plan_start(sample, topo.histories, vary, plan.n_variants, kernel, rec, companion)
    if start is None:
        return False, None, None
    do = decide(start, choice.background_min_seconds() < float("inf"))
    say = (lambda text: print(f"note: {text}", file=notes)) if notes is not None else (lambda text: None)

    def what(kinds: tuple[str, ...]) -> str:
        kernels = [k for k in kinds if k != start.companion]
        names = " and ".join(f"the {k} kernel" for k in kernels)
        beside = f" ({CRITERIA.label} beside it)" if start.companion in kinds else ""
        seconds = max([sum(start.costs[k] for k in kernels)] + [start.criteria] * (start.companion in kinds))
        return f"{names} for this model shape ({start.shape}; first run on this machine){beside}, ~{seconds:.0f} s"

    if do.foreground:
        say(f"compiling {what(do.foreground)}; Ctrl-C stops")
        choice.compile_foreground(
            do.foreground, sample, topo.histories, vary, interrupt.check, rec, say, companion
        )
    if do.now and choice.start_background(do.now, sample, topo.histories, vary, rec) is not None:
        say(
            f"compiling {what(do.now)} in the background"
            + (
                f"; the run starts on the NumPy reference (~{start.reference_seconds:.0f} s alone) and switches "
                "when it is ready"
                if do.small_chunks
                else ""
            )
        )
    elif do.small_chunks:
        return False, start.reference_seconds, None

    def later() -> None:
        if choice.start_background(do.after, sample, topo.histories, vary, rec) is not None:
            say(f"compiling {what(do.after)} in the background for the next run")

    return do.small_chunks, do.estimate, later if do.after else None
