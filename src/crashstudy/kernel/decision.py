"""How a run gets its kernels (:func:`decide`): compile some first, some in the background while it runs,
some after it, from what it is missing and what each way would cost (:class:`StartPlan`, made by
:func:`crashstudy.kernel.choice.plan_start` from a sample of the run's variants). A pure function of the
estimates, so that its cases are tested without a compile.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class StartPlan:
    """What a run is missing and what each choice would cost [s] (from a sample of its variants)."""

    costs: dict[str, float]  # compile seconds of each missing kernel ("generic", "generated")
    reference_seconds: float  # the whole run on the NumPy reference
    generic_seconds: float  # ... on the generic kernel (compile not included)
    fast_seconds: float  # ... on the fastest kernel once everything is compiled
    shape: str  # the model shape in words
    criteria: float = (
        0.0  # compile seconds of the companion (crash criteria) when the run needs it and it is missing
    )
    companion: str = "criteria"  # its name in the decision (Companion.name)

    @property
    def compile(self) -> tuple[str, ...]:
        """The missing kernels, cheapest first."""
        return tuple(sorted(self.costs, key=lambda k: self.costs[k]))

    @property
    def seconds(self) -> float:
        return sum(self.costs.values())


@dataclass
class Decision:
    """How a run gets its kernels: compile some first (in a child process, Ctrl-C stops it), some in the
    background while it runs, some in the background once it has finished (for the next run)."""

    estimate: float  # expected seconds of the run
    foreground: tuple[str, ...] = ()
    now: tuple[str, ...] = ()
    after: tuple[str, ...] = ()
    small_chunks: bool = (
        False  # run the reference in chunks of choice.REF_CHUNK so a finished compile is taken soon
    )


def decide(p: StartPlan, background: bool) -> Decision:
    """The fastest way through the run that is never slower than compiling the generic kernel first
    and running it, the way every run went before kernel choice (up to the estimates' error).

    - Nothing compiled, and the reference would take longer than compiling a kernel and running it:
      compile the kernel for which that is quicker first (this shape's generated one, unless the shape
      is large or the generated kernel cannot run it), the crash criteria beside it. When that is the
      generic kernel, this shape's generated one follows in the background, during the run when the
      run is long enough for it to pay back twice, else after it.
    - Nothing compiled, a shorter run: start on the reference and compile the quicker kernel in the
      background (on the other core), switching to it when it is ready.
    - The generic kernel compiled, this shape's generated one not: run on the generic kernel and compile
      the generated one in the background, during the run when it pays back twice, else after it.
    Without background compiles, only the foreground compiles that pay remain."""
    gen_cost = p.costs.get("generated")
    beside = (p.companion,) if p.criteria else ()
    if "generic" in p.costs:
        ways = {"generic": p.costs["generic"] + p.generic_seconds}
        if gen_cost is not None:
            ways["generated"] = gen_cost + p.fast_seconds
        first = min(ways, key=lambda k: ways[k])
        alone = ways[first] + max(0.0, p.criteria - p.costs[first])  # the criteria compile beside the kernel
        if p.reference_seconds > alone and first == "generated":
            return Decision(alone, foreground=("generated", *beside))
        if p.reference_seconds > alone:
            rest: tuple[str, ...] = ("generated",) if background and gen_cost is not None else ()
            during = gen_cost is not None and p.generic_seconds > 2 * gen_cost
            return Decision(
                alone,
                foreground=("generic", *beside),
                now=rest if during else (),
                after=() if during else rest,
            )
        if background:
            quick = "generated" if gen_cost is not None else "generic"
            return Decision(
                min(p.reference_seconds, p.costs[quick] + p.fast_seconds), now=(quick,), small_chunks=True
            )
        return Decision(p.reference_seconds)
    t_now = min(p.reference_seconds, p.generic_seconds)
    if gen_cost is None:
        return Decision(t_now)
    if background:
        return (
            Decision(t_now, now=("generated",))
            if t_now > 2 * gen_cost
            else Decision(t_now, after=("generated",))
        )
    if gen_cost + p.fast_seconds < t_now:
        return Decision(gen_cost + p.fast_seconds, foreground=("generated", *beside))
    return Decision(t_now)
