"""Model shape of a generated kernel: what its source depends on (topology, constant curves,
histories kept) and the layout every emitter shares (:func:`layout`: rows of the block work array).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from crashstudy import environment
from crashstudy.kernel.gen_constants import _const_layout, _constant_curves, _factor_curves
from crashstudy.vocabulary.codes import (
    ELASTOPLASTIC,
    ENERGIES,
    GENERAL,
    HISTORY_ORDER,
)
from crashstudy.vocabulary.materials import KNOT_MATERIALS, RATE_MATERIALS, spec

if TYPE_CHECKING:
    from crashstudy.arrays.batch import Batch

GEN_VERSION = 16  # bump when the generated source changes meaning (old cached kernels are ignored)
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
        return (f"the model has {len(b.spring_i)} springs, and a generated kernel is compiled for at most "
                f"{MAX_GENERATED_SPRINGS} (its compile time and memory grow faster than the springs)")  # fmt: skip
    return None


# ---------------------------------------------------------------------------------------------
# shape of a model: what the source depends on


def _shape(b: Batch, histories: tuple[str, ...], vary: frozenset[int] | None = None,
           const: list[int] | None = None, record: tuple[int, ...] = ()) -> dict[str, Any]:  # fmt: skip
    """What the generated source depends on. ``const``: the constant curves when already known (a
    background compile gets them from the run, whose batch it does not have). ``record``: nodes whose
    acceleration is kept at every step (a key only when there are some: other shapes keep their source)."""
    N, D, _ = b.x0.shape
    pm_nodes = set(b.pm_node.tolist())
    static = [bool(np.all(b.free[n] == 0.0) and not np.any(b.v0[n] != 0.0) and n not in pm_nodes) for n in range(N)]
    sign = [int(b.sign[s, 0]) if np.all(b.sign[s] == b.sign[s, 0]) and abs(b.sign[s, 0]) == 1.0 else 0
            for s in range(len(b.spring_i))]  # fmt: skip
    const = _constant_curves(b, vary) if const is None else const
    rc = [b.rate_curve[b.rate_off[s] : b.rate_off[s + 1]].tolist() for s in range(len(b.spring_i))]
    return {
        "const": const, "fac": _factor_curves(b, vary, const), "sign": sign, "kcheck": np.flatnonzero(b.knot_check).tolist(),
        "version": GEN_VERSION, "block": BLOCK, "row": ROW, "N": N, "D": D, "S": len(b.spring_i),
        "gravity": bool(np.any(b.gravity != 0.0)), "term": bool(np.any(b.ke_fraction > 0.0)),
        "walls": [[n for n in range(N) if b.wall_nodes[k, n] != 0.0] for k in range(b.wall_nodes.shape[0])],
        "free": b.free.tolist(), "loads": [[int(n), int(c)] for n, c in zip(b.load_node, b.load_curve, strict=True)],
        "si": b.spring_i.tolist(), "sj": b.spring_j.tolist(), "mat": b.material.tolist(),
        "pre": [s for s in range(len(b.spring_i)) if np.any(b.e0[s] != 0.0)],
        "fragile": [s for s in range(len(b.spring_i)) if np.any(np.isfinite(b.fail_t[s]) | np.isfinite(b.fail_c[s]))],
        "ca": b.curve_a.tolist(), "cb": b.curve_b.tolist(), "off": b.curve_off.tolist(),
        "movable": [bool(np.any(b.free[n] > 0.0)) or n in pm_nodes for n in range(N)], "static": static,
        "pm": [[int(b.pm_node[k]), int(b.pm_dir[k]), int(b.pm_kind[k]), int(b.pm_curve[k])] for k in range(len(b.pm_node))],
        "hist": [h for h in HISTORY_ORDER if h in histories or (h in ENERGIES and any(e in histories for e in ENERGIES))],
        **({"record": [int(n) for n in record]} if record else {}),
        **({"rc": rc} if any(rc) else {}),  # rate_elastic: each spring's curves (a key only when there are some)
    }  # fmt: skip


class _Rows:
    """Row numbers of the block work array, handed out by name."""

    def __init__(self) -> None:
        self.n = 0
        self.at: dict[str, int] = {}

    def add(self, name: str) -> int:
        self.at[name] = self.n
        self.n += 1
        return self.at[name]

    def __getitem__(self, name: str) -> str:
        """The work-array element of row ``name`` for lane ``w``, as source text."""
        return f"Z[{self.at[name] * ROW} + w]"


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
    E0: str  # the row of the energy at t = 0
    ES: str  # the row of the energy scale
    kcheck: set[int]  # knots that can hold a peak of |force|
    knots: dict[int, list[int]]  # those knots per spring following that curve
    knotted: list[int]
    keep_a: set[int]  # nodes whose a^{n-1} is kept
    R: _Rows
    live: list[int]  # nodes that are not static
    rc: list[list[int]]  # rate_elastic: each spring's curves, in rate order
    ro: list[int]  # where they start in Batch.rate_at
    curves: list[int]  # every curve the source evaluates
    cname: dict[str, str]  # coefficient -> local constant
    record: list[int]  # nodes whose a^n is kept at every step
    co: Callable[[str], str]
    ramp: Callable[[int, str], str]
    L: list[str]
    emit: Callable[[str], None]


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
    E0 = "ein" if pre else "ke0"  # the row of the energy at t = 0
    ES = "esc" if pre else "ke0"  # the row of the energy scale KE0 + |IE0| (the error's and the stop tests' scale)
    kcheck = set(shape["kcheck"])
    # knots that can hold a peak of |force| (Batch.knot_check), per spring following that curve
    knots = {s: [k for k in range(off[ca[s]] + 1, off[ca[s] + 1] - 1) if k in kcheck]
             for s in range(S) if mat[s] in KNOT_MATERIALS and ca[s] >= 0}  # fmt: skip
    knotted = [s for s in range(S) if knots.get(s)]
    keep_a = {n for n in range(N) if not static[n] and (dampers or term or (movable[n] and any(
        n in (si[s], sj[s]) for s in knotted)))}  # a^{n-1} kept: dampers, knot crossings  # fmt: skip
    R = _Rows()
    for name in ("dt", "lim", "thr", "ke0", "err", "ken", "ien", "efl") + (("kef", "tmin", "stop") if term else ()) + (
            ("ein", "esc") if pre else ()):  # fmt: skip
        R.add(name)
    if ext:
        for name in ("work", "wmax"):
            R.add(name)
    if grav:
        for d in range(D):
            R.add(f"g{d}")
    for k in range(len(loads)):
        for d in range(D):
            R.add(f"lf{k}_{d}")
    for k in range(len(pm)):
        R.add(f"pms{k}")
        R.add(f"pma{k}")
    if pm:
        R.add("nst")
    if D > 1:
        R.add("crushed")
    if W:
        R.add("wall_e")
    for wl in range(W):
        R.add(f"pw{wl}")
        R.add(f"wi{wl}")
        R.add(f"wk{wl}")
        if "wall_force" in hist:
            R.add(f"wf{wl}")
        for d in range(D):
            R.add(f"wn{wl}_{d}")
            R.add(f"wp{wl}_{d}")
        for n in walls[wl]:
            for d in range(D if not static[n] else 0):
                R.add(f"jp{wl}_{n}_{d}")
            if not static[n]:
                R.add(f"pen{wl}_{n}")
    live = [n for n in range(N) if not static[n]]
    for n in range(N if D > 1 else 0):
        if static[n]:
            for d in range(D):
                R.add(f"xs{n}_{d}")
    for n in live:
        for f in ("m", "pa"):
            R.add(f"{f}{n}")
        for d in range(D):
            for f in ("x", "x0", "v", "im") + (("a", "ao") if n in keep_a else ()) + (("v0",) if ext else ()) + (
                    ("fx",) if n in loaded else ()):  # fmt: skip
                R.add(f"{f}{n}_{d}")
    rc = shape.get("rc", [[] for _ in range(S)])  # rate_elastic: each spring's curves, in rate order
    ro = [sum(len(cs) for cs in rc[:s]) for s in range(S)]  # and where they start in Batch.rate_at
    curves = sorted({c for s in range(S) for c in (ca[s], cb[s]) if c >= 0} | set(tcurves) | {c for cs in rc for c in cs})
    cname = {nm: f"k_{nm}" for nm, _, _ in _const_layout(shape)}  # coefficient -> local constant
    fac = shape.get("fac", [])
    cmul: dict[str, str] = {}  # a factor curve's coefficient -> the row of its lane's factor
    for c in curves:
        if c in const:
            continue
        if c in fac:  # the shape in registers, the lane's factors ys, xs, ys / xs in rows
            for f in ("fy", "fx", "ff"):
                R.add(f"{f}{c}")
            cmul[f"cy0_{c}"], cmul[f"s0_{c}"] = R[f"fy{c}"], R[f"ff{c}"]
            for k in range(off[c], off[c + 1]):
                cmul[f"cx{k}"], cmul[f"ds{k}"] = R[f"fx{c}"], R[f"ff{c}"]
                if k in kcheck and k < off[c + 1] - 1:
                    R.add(f"kyv{k}")
            continue
        R.add(f"cy0_{c}")
        R.add(f"s0_{c}")
        for k in range(off[c], off[c + 1] - 1):
            R.add(f"cx{k}")
            if k > off[c]:
                R.add(f"ds{k}")
            if k in kcheck:
                R.add(f"kyv{k}")
        if c in tcurves:
            R.add(f"cx{off[c + 1] - 1}")
    for s in range(S):
        for f in ("kp", "fp", "ep", "ie", "pf", "mc", "me") + (("sg",) if D == 1 else ("l0",)) + (
                ("kh", "kth") if s in knotted else ()):  # fmt: skip
            R.add(f"{f}{s}")
        for d in range(D if s in knotted else 0):
            R.add(f"kdf{s}_{d}")
        for d in range(D if D > 1 else 0):
            R.add(f"ap{s}_{d}")  # previous direction (un-normalised)
        for k in range(0 if s in general else spec(mat[s]).state_rows):  # general_nonlinear's follow its rows below
            R.add(f"st{s}_{k}")
        if mat[s] == ELASTOPLASTIC:
            R.add(f"kt{s}")
            R.add(f"fy{s}")
        for k in range(len(rc[s])):
            R.add(f"rt{s}_{k}")
        if s in pre:
            R.add(f"e0{s}")
            R.add(f"r0{s}")
        if s in fragile:
            for f in ("ft", "fc", "br"):
                R.add(f"{f}{s}")
    for s in general:
        for f in ("yt", "yc", "F", "E", "rev") + (("gkc", "gkx", "gky", "gksh") if s in knotted else ()) + (
                ("ed",) if term else ()):  # fmt: skip
            R.add(f"{f}{s}")
        for d in range(D if D > 1 else 0):
            R.add(f"ax{s}_{d}")
        for k in range(spec(GENERAL).state_rows):
            R.add(f"st{s}_{k}")
    record = shape.get("record", [])  # a^n of these nodes at every step (crash criteria)
    for n in record:
        for d in range(D):
            R.add(f"am{n}_{d}")
    if "acceleration" in hist:  # a^n of a wall node with the walls' contact forces
        for n in sorted({n for wn in walls for n in wn} - {n for n in range(N) if static[n]}):
            for d in range(D):
                R.add(f"wa{n}_{d}")
    if hist:
        for n in live:
            for d in range(D):
                R.add(f"xh{n}_{d}")
                R.add(f"vh{n}_{d}")
        for s in range(S):
            for d in range(D if D > 1 else 0):
                R.add(f"axh{s}_{d}")

    def co(name: str) -> str:
        """A curve coefficient as source: a register, a register times the lane's factor, or a row."""
        if name in cname:
            return f"({cname[name]} * {cmul[name]})" if name in cmul else cname[name]
        return R[name]

    def ramp(c: int, arg: str) -> str:
        a0, b0 = off[c], off[c + 1]
        out = f"ramp_start({co(f'cy0_{c}')}, {co(f's0_{c}')}, {arg}, {co(f'cx{a0}')})"
        for k in range(a0 + 1, b0 - 1):
            out = f"ramp_knot({out}, {co(f'ds{k}')}, {arg}, {co(f'cx{k}')})"
        return out

    L: list[str] = []
    emit = L.append
    return Layout(
        N, S, D, W, si, sj, mat, ca, cb, off, static, movable, hist, const, fac, sign, grav, term, walls, free, loads,
        pm, ext, tcurves, loaded, general, fragile, pre, E0, ES, kcheck, knots, knotted, keep_a, R, live, rc, ro,
        curves, cname, record, co, ramp, L, emit,
    )
