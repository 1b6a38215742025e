"""Model shape of a generated kernel: what its source depends on (topology, constant curves,
histories kept) and the layout every emitter shares (:func:`layout`: rows of the block work array).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from crashstudy import environment
from crashstudy.kernel.gen_constants import _const_layout, _constant_curves, _factor_curves
from crashstudy.kernel.gen_rows import Coef, CoefName, Rows, Scalar, coef_name
from crashstudy.vocabulary.codes import (
    ELASTOPLASTIC,
    ENERGIES,
    GENERAL,
    HISTORY_ORDER,
)
from crashstudy.vocabulary.materials import KNOT_MATERIALS, RATE_MATERIALS, spec

if TYPE_CHECKING:
    from crashstudy.arrays.batch import Batch

GEN_VERSION = 21  # bump when the generated source changes meaning (old cached kernels are ignored)
BLOCK = environment.gen_block()  # variants per block (CRASHSTUDY_GEN_BLOCK)
ROW = BLOCK + 8  # row stride of the work array: not a power of two (rows 2 KiB apart alias in L1)


MAX_KNOTS = 150  # knots of one curve above which the emitted sums nest too deep for Python's parser
# springs above which a model gets no generated kernel: its one unrolled function compiles in time and memory
# growing faster than linearly (benchmarks/results/compile_springs.md: 32 springs ~60 CPU s, 64 ~200 s and
# 0.55 GB; a 1179-spring grid passed 11 GB before it was stopped); the generic kernel runs such models
MAX_GENERATED_SPRINGS = 64


def unsupported(b: Batch) -> str | None:
    """Why a generated kernel cannot run ``b`` (None if it can)."""
    knots = int(np.max(np.diff(b.curve_off), initial=0))
    if knots > MAX_KNOTS:
        return f"a curve has {knots} knots (the generated kernel takes at most {MAX_KNOTS})"
    if len(b.spring_i) > MAX_GENERATED_SPRINGS:
        return (
            f"the model has {len(b.spring_i)} springs, and a generated kernel is compiled for at most "
            f"{MAX_GENERATED_SPRINGS} (its compile time and memory grow faster than the springs)"
        )
    return None


# ---------------------------------------------------------------------------------------------
# shape of a model: what the source depends on


def _shape(
    b: Batch,
    histories: tuple[str, ...],
    vary: frozenset[int] | None = None,
    const: list[int] | None = None,
    record: tuple[int, ...] = (),
) -> dict[str, Any]:
    """What the generated source depends on. ``const``: the constant curves when already known (a
    background compile gets them from the run, whose batch it does not have). ``record``: nodes whose
    acceleration is kept at every step (a key only when there are some: other shapes keep their source)."""
    N, D, _ = b.x0.shape
    pm_nodes = set(b.pm_node.tolist())
    static = [
        bool(np.all(b.free[n] == 0.0) and not np.any(b.v0[n] != 0.0) and n not in pm_nodes) for n in range(N)
    ]
    sign = [
        int(b.sign[s, 0]) if np.all(b.sign[s] == b.sign[s, 0]) and abs(b.sign[s, 0]) == 1.0 else 0
        for s in range(len(b.spring_i))
    ]
    const = _constant_curves(b, vary) if const is None else const
    rc = [b.rate_curve[b.rate_off[s] : b.rate_off[s + 1]].tolist() for s in range(len(b.spring_i))]
    return {
        "const": const,
        "fac": _factor_curves(b, vary, const),
        "sign": sign,
        "kcheck": np.flatnonzero(b.knot_check).tolist(),
        "version": GEN_VERSION,
        "block": BLOCK,
        "row": ROW,
        "N": N,
        "D": D,
        "S": len(b.spring_i),
        "gravity": bool(np.any(b.gravity != 0.0)),
        "term": bool(np.any(b.ke_fraction > 0.0)),
        "walls": [[n for n in range(N) if b.wall_nodes[k, n] != 0.0] for k in range(b.wall_nodes.shape[0])],
        "free": b.free.tolist(),
        "loads": [[int(n), int(c)] for n, c in zip(b.load_node, b.load_curve, strict=True)],
        "si": b.spring_i.tolist(),
        "sj": b.spring_j.tolist(),
        "mat": b.material.tolist(),
        "pre": [s for s in range(len(b.spring_i)) if np.any(b.e0[s] != 0.0)],
        "fragile": [
            s for s in range(len(b.spring_i)) if np.any(np.isfinite(b.fail_t[s]) | np.isfinite(b.fail_c[s]))
        ],
        "ca": b.curve_a.tolist(),
        "cb": b.curve_b.tolist(),
        "off": b.curve_off.tolist(),
        "movable": [bool(np.any(b.free[n] > 0.0)) or n in pm_nodes for n in range(N)],
        "static": static,
        "pm": [
            [int(b.pm_node[k]), int(b.pm_dir[k]), int(b.pm_kind[k]), int(b.pm_curve[k])]
            for k in range(len(b.pm_node))
        ],
        "hist": [
            h
            for h in HISTORY_ORDER
            if h in histories or (h in ENERGIES and any(e in histories for e in ENERGIES))
        ],
        **({"record": [int(n) for n in record]} if record else {}),
        **(
            {"rc": rc} if any(rc) else {}
        ),  # rate_elastic: each spring's curves (a key only when there are some)
    }


def _lsum(terms: list[str]) -> str:
    """Source of ``0.0 + t0 + t1 + ...`` added left to right, as the reference's accumulating loops."""
    return "(" * len(terms) + "0.0" + "".join(f" + {t})" for t in terms)


@dataclass(frozen=True)
class Layout:
    """What the emitters (gen_source, gen_springs, gen_nodes) share for one shape: its topology, the rows
    of the work array ``R``, the source lines ``L`` (``emit`` appends one), the curve emitters ``co`` and
    ``ramp``. Built by :func:`layout`; lists are indexed by node ``n``, spring ``s``, wall ``wl``, curve ``c``."""

    N: int  # nodes
    S: int  # springs
    D: int  # dimensions
    W: int  # walls
    si: list[int]  # spring end nodes
    sj: list[int]
    mat: list[int]  # material codes
    ca: list[int]  # curve_a / curve_b of each spring (-1: none)
    cb: list[int]
    off: list[int]  # curve c's knots are off[c]:off[c + 1]
    static: list[bool]  # a node that never moves (no free direction, no velocity, not driven)
    movable: list[bool]
    hist: list[str]  # histories kept, in HISTORY_ORDER
    const: list[int]  # curves whose points are constants of the source
    fac: list[int]  # curves that are a constant shape times per-lane factors
    sign: list[int]  # 1-D: each spring's axis sign when all lanes share it (0: per lane)
    grav: bool
    term: bool  # early termination
    walls: list[list[int]]  # the nodes each wall holds
    free: list[list[float]]  # (N, D) 1.0 where the dof moves under forces
    loads: list[list[int]]  # [node, time curve (-1: constant)]
    pm: list[list[int]]  # prescribed motion: [node, direction, kind, curve]
    ext: bool  # external work to book
    tcurves: list[int]  # time curves (loads, prescribed motion)
    loaded: set[int]  # nodes whose external force changes in time
    general: list[int]  # general_nonlinear springs
    fragile: list[int]  # springs that can break
    pre: list[int]  # preloaded springs
    E0: Scalar  # the row of the energy at t = 0
    ES: Scalar  # the row of the energy scale
    kcheck: set[int]  # knots that can hold a peak of |force|
    knots: dict[int, list[int]]  # those knots per spring following that curve
    knotted: list[int]
    keep_a: set[int]  # nodes whose a^{n-1} is kept
    R: Rows
    live: list[int]  # nodes that are not static
    rc: list[list[int]]  # rate_elastic: each spring's curves, in rate order
    ro: list[int]  # where they start in Batch.rate_at
    curves: list[int]  # every curve the source evaluates
    cname: dict[Coef, str]  # coefficient -> local constant
    record: list[int]  # nodes whose a^n is kept at every step
    co: Callable[[CoefName, int], str]
    ramp: Callable[[int, str], str]
    L: list[str]
    emit: Callable[[str], None]
    tables: list[list[list[int]]] = field(default_factory=list)  # constant tables of the source (gen_loops)

    def table(self, rows: list[list[int]]) -> str:
        """The name of a module constant holding ``rows`` (an int64 array; one per distinct content)."""
        if rows not in self.tables:
            self.tables.append(rows)
        return f"_T{self.tables.index(rows)}"


def layout(shape: dict[str, Any]) -> Layout:
    """Everything the emitters share for ``shape``: its numbers, the rows of the work array ``R``, the
    source lines ``L`` (``emit`` appends one) and the curve emitters ``co``/``ramp``."""
    N, S, D = shape["N"], shape["S"], shape["D"]
    si, sj, mat, ca, cb, off = shape["si"], shape["sj"], shape["mat"], shape["ca"], shape["cb"], shape["off"]
    static, movable, hist = shape["static"], shape["movable"], shape["hist"]
    const, sign, grav, term = shape["const"], shape["sign"], shape["gravity"], shape["term"]
    walls, free, loads, pm = shape["walls"], shape["free"], shape["loads"], shape["pm"]
    W = len(walls)
    ext = grav or bool(loads) or bool(pm)  # external work to book
    tcurves = sorted({c for _, c in loads if c >= 0} | {c for _, _, _, c in pm})
    loaded = {n for n, _ in loads} | {p for p, _, _, _ in pm}  # nodes whose external force changes in time
    general = [s for s in range(S) if mat[s] == GENERAL]
    dampers = any(mat[s] in RATE_MATERIALS for s in range(S))
    fragile = shape["fragile"]  # springs that can break (failure): thresholds and a broken flag
    pre = shape["pre"]  # preloaded springs (initial_elongation): e0, the rate at t = 0, KE0 + IE0
    E0: Scalar = "ein" if pre else "ke0"  # the row of the energy at t = 0
    ES: Scalar = (
        "esc" if pre else "ke0"
    )  # the row of the energy scale KE0 + |IE0| (the error's and the stop tests' scale)
    kcheck = set(shape["kcheck"])
    # knots that can hold a peak of |force| (Batch.knot_check), per spring following that curve
    knots = {
        s: [k for k in range(off[ca[s]] + 1, off[ca[s] + 1] - 1) if k in kcheck]
        for s in range(S)
        if mat[s] in KNOT_MATERIALS and ca[s] >= 0
    }
    knotted = [s for s in range(S) if knots.get(s)]
    keep_a = {
        n
        for n in range(N)
        if not static[n] and (dampers or term or (movable[n] and any(n in (si[s], sj[s]) for s in knotted)))
    }  # a^{n-1} kept: dampers, knot crossings
    R = Rows(ROW)
    R.each(("dt", "lim", "thr", "ke0", "err", "ken", "ien", "efl"))
    if term:
        R.each(("kef", "tmin", "stop"))
    if pre:
        R.each(("ein", "esc"))
    if ext:
        R.each(("work", "wmax"))
    if grav:
        for d in range(D):
            R.add("g", d)
    for k in range(len(loads)):
        for d in range(D):
            R.add("lf", k, d)
    for k in range(len(pm)):
        R.add("pms", k)
        R.add("pma", k)
    if pm:
        R.add("nst")
    if D > 1:
        R.add("crushed")
    if W:
        R.add("wall_e")
    for wl in range(W):
        R.add("pw", wl)
        R.add("wi", wl)
        R.add("wk", wl)
        if "wall_force" in hist:
            R.add("wf", wl)
        for d in range(D):
            R.add("wn", wl, d)
            R.add("wp", wl, d)
        for n in walls[wl]:
            for d in range(D if not static[n] else 0):
                R.add("jp", wl, n, d)
            if not static[n]:
                R.add("pen", wl, n)
    live = [n for n in range(N) if not static[n]]
    for n in range(N if D > 1 else 0):
        if static[n]:
            for d in range(D):
                R.add("xs", n, d)
    for n in live:
        R.each(("m", "pa"), n)
        for d in range(D):
            R.each(("x", "x0", "v", "im"), n, d)
            if n in keep_a:
                R.each(("a", "ao"), n, d)
            if ext:
                R.add("v0", n, d)
            if n in loaded:
                R.add("fx", n, d)
    rc = shape.get("rc", [[] for _ in range(S)])  # rate_elastic: each spring's curves, in rate order
    ro = [sum(len(cs) for cs in rc[:s]) for s in range(S)]  # and where they start in Batch.rate_at
    curves = sorted(
        {c for s in range(S) for c in (ca[s], cb[s]) if c >= 0} | set(tcurves) | {c for cs in rc for c in cs}
    )
    cname = {
        key: f"k_{coef_name(key)}" for key, _, _ in _const_layout(shape)
    }  # coefficient -> local constant
    fac = shape.get("fac", [])
    cmul: dict[Coef, str] = {}  # a factor curve's coefficient -> the row of its lane's factor
    for c in curves:
        if c in const:
            continue
        if c in fac:  # the shape in registers, the lane's factors ys, xs, ys / xs in rows
            R.each(("cfy", "cfx", "cff"), c)
            cmul["cy0", c], cmul["s0", c] = R["cfy", c], R["cff", c]
            for k in range(off[c], off[c + 1]):
                cmul["cx", k], cmul["ds", k] = R["cfx", c], R["cff", c]
                if k in kcheck and k < off[c + 1] - 1:
                    R.add("kyv", k)
            continue
        R.add("cy0", c)
        R.add("s0", c)
        for k in range(off[c], off[c + 1] - 1):
            R.add("cx", k)
            if k > off[c]:
                R.add("ds", k)
            if k in kcheck:
                R.add("kyv", k)
        if c in tcurves:
            R.add("cx", off[c + 1] - 1)
    for s in range(S):
        R.each(("kp", "fp", "ep", "ie", "pf", "mc", "me"), s)
        R.add("sg" if D == 1 else "l0", s)
        if s in knotted:
            R.each(("kh", "kth"), s)
        for d in range(D if s in knotted else 0):
            R.add("kdf", s, d)
        for d in range(D if D > 1 else 0):
            R.add("ap", s, d)  # previous direction (un-normalised)
        for k in range(
            0 if s in general else spec(mat[s]).state_rows
        ):  # general_nonlinear's follow its rows below
            R.add("st", s, k)
        if mat[s] == ELASTOPLASTIC:
            R.each(("kt", "fy"), s)
        for k in range(len(rc[s])):
            R.add("rt", s, k)
        if s in pre:
            R.add("e0", s)
            R.add("r0", s)
        if s in fragile:
            R.each(("ft", "fc", "br"), s)
    for s in general:
        R.each(("yt", "yc", "F", "E", "rev"), s)
        if s in knotted:
            R.each(("gkc", "gkx", "gky", "gksh"), s)
        if term:
            R.add("ed", s)
        for d in range(D if D > 1 else 0):
            R.add("ax", s, d)
        for k in range(spec(GENERAL).state_rows):
            R.add("st", s, k)
    record = shape.get("record", [])  # a^n of these nodes at every step (crash criteria)
    for n in record:
        for d in range(D):
            R.add("am", n, d)
    if "acceleration" in hist:  # a^n of a wall node with the walls' contact forces
        for n in sorted({n for wn in walls for n in wn} - {n for n in range(N) if static[n]}):
            for d in range(D):
                R.add("wa", n, d)
    if hist:
        for n in live:
            for d in range(D):
                R.add("xh", n, d)
                R.add("vh", n, d)
        for s in range(S):
            for d in range(D if D > 1 else 0):
                R.add("axh", s, d)

    def co(name: CoefName, i: int) -> str:
        """Curve coefficient ``name`` of curve or knot ``i`` as source: a register, a register times the
        lane's factor, or a row."""
        if (name, i) in cname:
            return f"({cname[name, i]} * {cmul[name, i]})" if (name, i) in cmul else cname[name, i]
        return R[name, i]

    def ramp(c: int, arg: str) -> str:
        a0, b0 = off[c], off[c + 1]
        out = f"ramp_start({co('cy0', c)}, {co('s0', c)}, {arg}, {co('cx', a0)})"
        for k in range(a0 + 1, b0 - 1):
            out = f"ramp_knot({out}, {co('ds', k)}, {arg}, {co('cx', k)})"
        return out

    L: list[str] = []
    emit = L.append
    return Layout(
        N,
        S,
        D,
        W,
        si,
        sj,
        mat,
        ca,
        cb,
        off,
        static,
        movable,
        hist,
        const,
        fac,
        sign,
        grav,
        term,
        walls,
        free,
        loads,
        pm,
        ext,
        tcurves,
        loaded,
        general,
        fragile,
        pre,
        E0,
        ES,
        kcheck,
        knots,
        knotted,
        keep_a,
        R,
        live,
        rc,
        ro,
        curves,
        cname,
        record,
        co,
        ramp,
        L,
        emit,
    )
