"""Model-specialised kernels: numba source generated from a batch's topology, compiled once, cached.

The generic kernel (:mod:`crashstudy.kernel.compiled`) reads the topology from arrays at run time:
which nodes a spring joins, its material, how many knots its curves have. Every step it loops over
springs and nodes and keeps a dozen separate block arrays, and LLVM vectorises few of its loops.
Here the topology is written into the source instead, the way a hand-specialised loop would be: one
fused, branch-free pass over the variants of a block per time step computes every spring, every
node update and every summary, with all per-variant numbers (masses, curve knots, stiffnesses,
state, summaries) in rows of ONE block work array ``Z`` with a compile-time row stride, so LLVM can
prove the rows never overlap and puts several variants in one SIMD instruction. Curves that no
study axis changes (and that are equal in every variant of the batch) are read once into local
constants; a spring's 1-D sign that is the same in every variant folds into the operators.

The arithmetic is that of the reference kernel, operation for operation, so results are bitwise
those of :func:`crashstudy.kernel.reference.run_reference` (``tests/test_generated.py``). The
numbers stay per variant: one compiled kernel serves every study of the same model shape.

Scope: every model the schema accepts (1-D and 2-D, every material, gravity, loads, prescribed
motion, rigid walls, early termination); :func:`unsupported` is where a future exception would go. Variants that end (end
time, termination, failure) leave their block once they are an eighth of it ("lane compaction":
their results are written, the running lanes move down), so later steps run over fewer lanes.

Units: whatever consistent system the model uses (the kernel only multiplies and adds; SI in the
examples: m, s, kg, N, J).

Compilation costs seconds per model shape, so the runner uses a generated kernel when the study is
large enough to earn it back, or when this shape's kernel is already compiled (numba's on-disk cache
next to the generated source, in the user's private folder of :mod:`crashstudy.kernel.cache`).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numba as nb
import numpy as np

from crashstudy.batch import Batch
from crashstudy.compiler import CRUSH, DAMPER, GENERAL, LINEAR, NONLINEAR, PM_ACCELERATION, PM_DISPLACEMENT
from crashstudy.kernel.cache import cache_dir, checked_dir, why_not_private
from crashstudy.kernel.compiled import get_threads
from crashstudy.kernel.output import HISTORY_ORDER, KernelOutput, allocate
from crashstudy.kernel.reference import TINY_LENGTH
from crashstudy.kernel.scalar import reverse_yield

GEN_VERSION = 8  # bump when the generated source changes meaning (old cached kernels are ignored)
BLOCK = int(os.environ.get("CRASHSTUDY_GEN_BLOCK", "256"))  # variants per block
ROW = BLOCK + 8  # row stride of the work array: not a power of two (rows 2 KiB apart alias in L1)
ENERGIES = ("kinetic_energy", "internal_energy", "external_work", "wall_energy")
_LOCK = threading.Lock()
_LOADED: dict[str, Any] = {}


@nb.njit(cache=True, nogil=True)
def reverse_yield_lane(e, st, w, ca, cb, yt, yc, v, cx, cy, cds, cs0, cs1, off):  # pragma: no cover - compiled
    """:func:`crashstudy.kernel.scalar.reverse_yield` compiled once, called (rarely) by every generated
    kernel instead of being inlined into each."""
    return reverse_yield(e, st, w, ca, cb, yt, yc, v, cx, cy, cds, cs0, cs1, off)


MAX_KNOTS = 150  # knots of one curve above which the emitted sums nest too deep for Python's parser


def unsupported(b: Batch) -> str | None:
    """Why a generated kernel cannot run ``b`` (None if it can)."""
    knots = int(np.max(np.diff(b.curve_off), initial=0))
    if knots > MAX_KNOTS:
        return f"a curve has {knots} knots (the generated kernel takes at most {MAX_KNOTS})"
    return None


# ---------------------------------------------------------------------------------------------
# shape of a model: what the source depends on


def _constant_curves(b: Batch, vary: frozenset[int] | None) -> list[int]:
    """Curves whose coefficients are the same in every variant of ``b`` and, when ``vary`` (curve
    indices a study varies) is given, not among those: their numbers stay in registers."""
    out = []
    for c in range(len(b.curve_off) - 1):
        a0, b0 = b.curve_off[c], b.curve_off[c + 1]
        if vary is not None and c in vary:
            continue
        rows = [b.cx[a0:b0], b.cy[a0:b0], b.cds[a0:b0], b.knot_y[a0:b0], b.cs0[c : c + 1]]
        if all(np.all(r == r[:, :1]) for r in rows):
            out.append(c)
    return out


def _const_layout(shape: dict[str, Any]) -> list[tuple[str, str, int]]:
    """(coefficient name, Batch array, row) of every constant-curve coefficient the springs read, in
    the order of the kernel's ``cst`` argument."""
    off, S = shape["off"], shape["S"]
    tcurves = {c for _, c in shape["loads"] if c >= 0} | {c for _, _, _, c in shape["pm"]}
    used = {c for s in range(S) for c in (shape["ca"][s], shape["cb"][s]) if c >= 0} | tcurves
    out = []
    for c in shape["const"]:
        if c not in used:
            continue
        if c in tcurves:
            out.append((f"cx{off[c + 1] - 1}", "cx", off[c + 1] - 1))
        out += [(f"cy0_{c}", "cy", off[c]), (f"s0_{c}", "cs0", c)]
        for k in range(off[c], off[c + 1] - 1):
            out.append((f"cx{k}", "cx", k))
            if k > off[c]:
                out.append((f"ds{k}", "cds", k))
            if k in shape["kcheck"]:
                out.append((f"kyv{k}", "knot_y", k))
    return out


def _constants(b: Batch, shape: dict[str, Any]) -> np.ndarray:
    """The ``cst`` argument: the constant curves' coefficients (the same in every variant)."""
    return np.array([getattr(b, arr)[row, 0] for _, arr, row in _const_layout(shape)] + [0.0])


def _shape(b: Batch, histories: tuple[str, ...], vary: frozenset[int] | None = None,
           const: list[int] | None = None) -> dict[str, Any]:  # fmt: skip
    """What the generated source depends on. ``const``: the constant curves when already known (a
    background compile gets them from the run, whose batch it does not have)."""
    N, D, _ = b.x0.shape
    pm_nodes = set(b.pm_node.tolist())
    static = [bool(np.all(b.free[n] == 0.0) and not np.any(b.v0[n] != 0.0) and n not in pm_nodes) for n in range(N)]
    sign = [int(b.sign[s, 0]) if np.all(b.sign[s] == b.sign[s, 0]) and abs(b.sign[s, 0]) == 1.0 else 0
            for s in range(len(b.spring_i))]  # fmt: skip
    return {
        "const": _constant_curves(b, vary) if const is None else const, "sign": sign, "kcheck": np.flatnonzero(b.knot_check).tolist(),
        "version": GEN_VERSION, "block": BLOCK, "row": ROW, "N": N, "D": D, "S": len(b.spring_i),
        "gravity": bool(np.any(b.gravity != 0.0)), "term": bool(np.any(b.ke_fraction > 0.0)),
        "walls": [[n for n in range(N) if b.wall_nodes[k, n] != 0.0] for k in range(b.wall_nodes.shape[0])],
        "free": b.free.tolist(), "loads": [[int(n), int(c)] for n, c in zip(b.load_node, b.load_curve, strict=True)],
        "si": b.spring_i.tolist(), "sj": b.spring_j.tolist(), "mat": b.material.tolist(),
        "ca": b.curve_a.tolist(), "cb": b.curve_b.tolist(), "off": b.curve_off.tolist(),
        "movable": [bool(np.any(b.free[n] > 0.0)) or n in pm_nodes for n in range(N)], "static": static,
        "pm": [[int(b.pm_node[k]), int(b.pm_dir[k]), int(b.pm_kind[k]), int(b.pm_curve[k])] for k in range(len(b.pm_node))],
        "hist": [h for h in HISTORY_ORDER if h in histories or (h in ENERGIES and any(e in histories for e in ENERGIES))],
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


def _source(shape: dict[str, Any]) -> str:
    """The module source of the kernel for ``shape`` (see the module docstring)."""
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
    dampers = any(mat[s] == DAMPER for s in range(S))
    kcheck = set(shape["kcheck"])
    # knots that can hold a peak of |force| (Batch.knot_check), per spring following that curve
    knots = {s: [k for k in range(off[ca[s]] + 1, off[ca[s] + 1] - 1) if k in kcheck]
             for s in range(S) if mat[s] in (NONLINEAR, CRUSH, GENERAL) and ca[s] >= 0}  # fmt: skip
    knotted = [s for s in range(S) if knots.get(s)]
    keep_a = {n for n in range(N) if not static[n] and (dampers or term or (movable[n] and any(
        n in (si[s], sj[s]) for s in knotted)))}  # fmt: skip  (a^{n-1} kept: dampers, knot crossings)
    R = _Rows()
    for name in ("dt", "lim", "thr", "ke0", "err", "ken", "ien", "efl") + (("kef", "tmin", "stop") if term else ()):
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
        if "wall_force" in hist:
            R.add(f"wf{wl}")
        for d in range(D):
            R.add(f"wn{wl}_{d}")
            R.add(f"wp{wl}_{d}")
        for n in walls[wl]:
            for d in range(D if not static[n] else 0):
                R.add(f"jp{wl}_{n}_{d}")
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
    curves = sorted({c for s in range(S) for c in (ca[s], cb[s]) if c >= 0} | set(tcurves))
    cname = {nm: f"k_{nm}" for nm, _, _ in _const_layout(shape)}  # coefficient -> local constant
    for c in curves:
        if c in const:
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
        for f in ("kp", "fp", "ep", "ie", "pf", "mc") + (("sg",) if D == 1 else ("l0",)) + (
                ("kh", "kth") if s in knotted else ()):  # fmt: skip
            R.add(f"{f}{s}")
        for d in range(D if s in knotted else 0):
            R.add(f"kdf{s}_{d}")
        for d in range(D if D > 1 else 0):
            R.add(f"ap{s}_{d}")  # previous direction (un-normalised)
        if mat[s] == CRUSH:
            R.add(f"st{s}_0")
            R.add(f"st{s}_1")
    gs_row = {}
    for s in general:
        for f in ("yt", "yc", "F", "E", "rev") + (("gkc", "gkx", "gky", "gksh") if s in knotted else ()) + (
                ("ed",) if term else ()):  # fmt: skip
            R.add(f"{f}{s}")
        for d in range(D if D > 1 else 0):
            R.add(f"ax{s}_{d}")
        gs_row[s] = R.n
        for k in range(8):
            R.add(f"st{s}_{k}")
    if hist:
        for n in live:
            for d in range(D):
                R.add(f"xh{n}_{d}")
                R.add(f"vh{n}_{d}")
        for s in range(S):
            for d in range(D if D > 1 else 0):
                R.add(f"axh{s}_{d}")

    def co(name: str) -> str:
        return cname[name] if name in cname else R[name]

    def ramp(c: int, arg: str) -> str:
        a0, b0 = off[c], off[c + 1]
        out = f"({co(f'cy0_{c}')} + {co(f's0_{c}')} * ({arg} - {co(f'cx{a0}')}))"
        for k in range(a0 + 1, b0 - 1):
            out = f"({out} + {co(f'ds{k}')} * _max(0.0, {arg} - {co(f'cx{k}')}))"
        return out

    L: list[str] = []
    emit = L.append

    def geometry(ind: str, springs: list[int], pass_a: bool) -> None:
        """Elongation ``e{s}`` (and in 2-D the unit direction ``ax{s}_{d}``) of ``springs``, as the
        reference computes them; 2-D also updates the previous direction and the collapse flag."""
        if D == 1:
            for n in sorted({m for s in springs for m in (si[s], sj[s])}):
                if not static[n]:
                    emit(f"{ind}d{n} = {R[f'x{n}_0']} - {R[f'x0{n}_0']}")
            for s in springs:
                body = f"({'0.0' if static[sj[s]] else f'd{sj[s]}'} - {'0.0' if static[si[s]] else f'd{si[s]}'})"
                if sign[s] == 1:  # 1.0 * y == y and -1.0 * y == -y exactly
                    emit(f"{ind}e{s} = {body}")
                elif sign[s] == -1:
                    emit(f"{ind}e{s} = -{body}")
                else:
                    emit(f"{ind}e{s} = {R[f'sg{s}']} * {body}")
            return
        for s in springs:
            i, j = si[s], sj[s]
            for d in range(D):
                xj = R[f"xs{j}_{d}"] if static[j] else R[f"x{j}_{d}"]
                xi = R[f"xs{i}_{d}"] if static[i] else R[f"x{i}_{d}"]
                emit(f"{ind}u{d} = {xj} - {xi}")
            emit(f"{ind}ln = np.sqrt({_lsum([f'u{d} * u{d}' for d in range(D)])})")
            emit(f"{ind}turn = {_lsum([f'u{d} * ' + R[f'ap{s}_{d}'] for d in range(D)])}")
            for d in range(D):
                emit(f"{ind}{R[f'ap{s}_{d}']} = u{d}")
            emit(f"{ind}gone = (ln <= {TINY_LENGTH!r} * {R[f'l0{s}']}) | (turn <= 0.0)")
            if not pass_a:  # the first collapsed spring in spring order (pass A's ones come first: see below)
                emit(f"{ind}{R['crushed']} = {float(s)!r} if (gone and {R['crushed']} < 0.0) else {R['crushed']}")
            else:
                emit(f"{ind}gone{s} = gone")
            emit(f"{ind}dn = 1.0 if gone else ln")
            for d in range(D):
                emit(f"{ind}ax{s}_{d} = u{d} / dn")
            emit(f"{ind}e{s} = ln - {R[f'l0{s}']}")

    def knot_search(ind: str, s: int, lo: str, hi: str, shift: str, ep: str, out: tuple[str, str, str]) -> None:
        """Candidate |force| of the flagged knots of spring s's curve on the path (lo, hi) (abscissa of
        the curve), with the abscissa and force of the knot that gave it: ``out`` (kc, kx, ky), as
        kernel.compiled's knot loop (``knot_peak``, the first knot starting from 0)."""
        kc, kx, ky = out
        for idx, k in enumerate(knots[s]):
            yk = f"_min(0.0, {co(f'kyv{k}')})" if mat[s] == CRUSH else co(f"kyv{k}")
            emit(f"{ind}yk = {yk}")
            emit(f"{ind}xk = {co(f'cx{k}')}")
            c0, xs0, ys0 = ("0.0", f"({ep} - {shift})", "0.0") if idx == 0 else (kc, kx, ky)
            emit(f"{ind}c1 = knot_peak({c0}, {lo}, {hi}, xk, yk)")
            emit(f"{ind}{kx} = xk if c1 > {c0} else {xs0}")
            emit(f"{ind}{ky} = yk if c1 > {c0} else {ys0}")
            emit(f"{ind}{kc} = c1")

    def knot_post(ind: str, s: int, kc: str, kx: str, ky: str, sh: str) -> None:
        """The crossing of spring s's winning knot: peak-force candidate, crossing fraction ``th{s}`` and
        (knot force - force interpolated in time) x axis ``dfax{s}_{d}`` (see kernel.compiled)."""
        fp = R[f"fp{s}"]
        emit(f"{ind}hit{s} = ({kc} > 0.0) & (wt > 0.0)")
        emit(f"{ind}epa = {R[f'ep{s}']} - {sh}")
        emit(f"{ind}ea = e{s} - {sh}")
        emit(f"{ind}th = ({kx} - epa) / ((ea - epa) if {kc} > 0.0 else 1.0)")
        emit(f"{ind}dF = ({ky} - ((1.0 - th) * {fp} + th * F{s})) if {kc} > 0.0 else 0.0")
        emit(f"{ind}{R[f'kth{s}']} = th")
        emit(f"{ind}{R[f'kh{s}']} = 1.0 if hit{s} else 0.0")
        emit(f"{ind}nhit += 1 if hit{s} else 0")
        for d in range(D):
            axis = f"ax{s}_{d}" if D > 1 else {1: "1.0", -1: "-1.0", 0: R[f"sg{s}"]}[sign[s]]
            emit(f"{ind}{R[f'kdf{s}_{d}']} = dF * {axis}")
        emit(f"{ind}{R[f'pf{s}']} = _max({R[f'pf{s}']}, {kc} * afw)")

    def time_curve(ind: str, name: str, c: int, t: str) -> None:
        """``name`` = time curve c at time ``t`` (0 outside its first..last knot, with kernel.scalar's
        1e-9 margin), branch-free."""
        cx0, cxl = co(f"cx{off[c]}"), co(f"cx{off[c + 1] - 1}")
        emit(f"{ind}tt = {t}")
        emit(f"{ind}eps = 1e-9 * ({cxl} - {cx0})")
        emit(f"{ind}{name} = 0.0 if ((tt < {cx0} - eps) | (tt > {cxl} + eps)) else {ramp(c, 'tt')}")

    def vp(n: int, d: int) -> str:
        return "0.0" if static[n] else f"({R[f'v{n}_{d}']} + 0.5 * dtw * {R[f'a{n}_{d}']})"

    def edot(s: int) -> str:
        """Elongation rate of spring s from v^{n-1/2} + dt/2 a^{n-1} (dampers; termination's opening test)."""
        if D == 1:
            sg = {1: "1.0", -1: "-1.0", 0: R[f"sg{s}"]}[sign[s]]
            return f"({sg} * ({vp(sj[s], 0)} - {vp(si[s], 0)}))"
        return _lsum([f"ax{s}_{d} * ({vp(sj[s], d)} - {vp(si[s], d)})" for d in range(D)])

    # ---- pass A: general_nonlinear springs (rules 1-3 branch-free; reversals flagged) ----
    def pass_a(ind: str) -> None:
        emit(f"{ind}nrev = 0")
        emit(f"{ind}for w in range(B):")
        i2 = ind + "    "
        emit(f"{i2}dtw = {R['dt']}")
        geometry(i2, general, True)
        if term:
            for s in general:
                emit(f"{i2}{R[f'ed{s}']} = {edot(s)}")
        for s in general:
            st = [R[f"st{s}_{k}"] for k in range(8)]
            emit(f"{i2}e = e{s}")
            if D > 1:
                for d in range(D):
                    emit(f"{i2}{R[f'ax{s}_{d}']} = ax{s}_{d}")
                emit(f"{i2}{R[f'rev{s}']} = 2.0 if gone{s} else 0.0  # collapsed: kept for pass B")
            emit(f"{i2}mode = {st[0]}")
            emit(f"{i2}et = {st[1]}")
            emit(f"{i2}ft = {st[2]}")
            emit(f"{i2}ec = {st[3]}")
            emit(f"{i2}fc = {st[4]}")
            emit(f"{i2}ytw = {R[f'yt{s}']}")
            emit(f"{i2}ycw = {R[f'yc{s}']}")
            if s in knotted:  # on the loading curve, in its own (shifted) abscissa; state before the step
                ep = R[f"ep{s}"]
                emit(f"{i2}sh = {st[5]}")
                emit(f"{i2}lo_ = et if mode > 0 else (e if mode < 0 else _min({ep}, e))")
                emit(f"{i2}hi_ = e if mode > 0 else (ec if mode < 0 else _max({ep}, e))")
                knot_search(i2, s, "lo_ - sh", "hi_ - sh", "sh", ep,
                            (R[f"gkc{s}"], R[f"gkx{s}"], R[f"gky{s}"]))  # fmt: skip
                emit(f"{i2}{R[f'gksh{s}']} = sh")
            emit(f"{i2}L = {ramp(ca[s], f'(e - {st[5]})')}")
            emit(f"{i2}Ut = {ramp(cb[s], '(e - et)')}")
            emit(f"{i2}Uc = {ramp(cb[s], '(e - ec)')}")
            emit(f"{i2}thr_t = ft if {st[6]} > 0 else ytw")
            emit(f"{i2}thr_c = fc if {st[7]} > 0 else ycw")
            emit(f"{i2}is0 = mode == 0")
            emit(f"{i2}ist = mode > 0")
            emit(f"{i2}isc = mode < 0")
            emit(f"{i2}on_l = ist & (e >= et)")
            emit(f"{i2}on_lc = isc & (e <= ec)")
            emit(f"{i2}bt = ft + Ut")
            emit(f"{i2}bc = fc + Uc")
            emit(f"{i2}{R[f'F{s}']} = L if (is0 | on_l | on_lc) else (bt if ist else bc)")
            emit(f"{i2}{R[f'E{s}']} = e")
            emit(f"{i2}to_t = is0 & (L >= ytw)")
            emit(f"{i2}to_c = is0 & (L <= ycw)")
            emit(f"{i2}rev = (ist & (not on_l) & (bt <= thr_c)) | (isc & (not on_lc) & (bc >= thr_t))")
            emit(f"{i2}{R[f'rev{s}']} = {R[f'rev{s}']} + 1.0 if rev else {R[f'rev{s}']}"
                 if D > 1 else f"{i2}{R[f'rev{s}']} = 1.0 if rev else 0.0")  # fmt: skip
            emit(f"{i2}nrev += 1 if rev else 0")
            emit(f"{i2}{st[1]} = e if (on_l | to_t) else et")
            emit(f"{i2}{st[2]} = L if (on_l | to_t) else ft")
            emit(f"{i2}{st[3]} = e if (on_lc | to_c) else ec")
            emit(f"{i2}{st[4]} = L if (on_lc | to_c) else fc")
            emit(f"{i2}{st[0]} = 1.0 if to_t else (-1.0 if to_c else mode)")
            emit(f"{i2}{st[6]} = 1.0 if to_t else {st[6]}")
            emit(f"{i2}{st[7]} = 1.0 if to_c else {st[7]}")
        emit(f"{ind}if nrev > 0:")
        for s in general:
            emit(f"{ind}    for w in range(B):")
            emit(f"{ind}        if {R[f'rev{s}']} == 1.0 or {R[f'rev{s}']} == 3.0:")
            emit(f"{ind}            {R[f'F{s}']} = reverse_yield_lane({R[f'E{s}']}, gst{s}, w, {ca[s]}, {cb[s]}, "
                 f"{R[f'yt{s}']}, {R[f'yc{s}']}, vi[w], cx, cy, cds, cs0, cs1, off)")  # fmt: skip

    # ---- pass B: every other spring, summaries, node updates, energy balance ----
    def pass_k(ind: str) -> None:
        """|a| at this step's knot crossings (only run when a lane crossed one): a interpolated in time
        plus the kinked spring's correction, as kernel.compiled (rows kth, kdf, kh, ao, a)."""
        emit(f"{ind}if nhit > 0:")
        emit(f"{ind}    for w in range(B):")
        i2 = ind + "        "
        emit(f"{i2}af = 1.0 if fn <= {R['lim']} else 0.0")
        for s in knotted:
            emit(f"{i2}th = {R[f'kth{s}']}")
            for p, op in ((si[s], "+"), (sj[s], "-")):
                if static[p] or not movable[p]:
                    continue
                emit(f"{i2}a2 = 0.0")
                for d in range(D):
                    emit(f"{i2}ai = (1.0 - th) * {R[f'ao{p}_{d}']} + th * {R[f'a{p}_{d}']}")
                    emit(f"{i2}ai = ai {op} {R[f'kdf{s}_{d}']} * {R[f'im{p}_{d}']}")
                    emit(f"{i2}a2 = a2 + ai * ai")
                emit(f"{i2}{R[f'pa{p}']} = _max({R[f'pa{p}']}, (a2 if {R[f'kh{s}']} > 0.0 else 0.0) * af)")

    def pass_b(ind: str) -> None:
        emit(f"{ind}nbad = 0")
        emit(f"{ind}nhit = 0")
        emit(f"{ind}nstop = 0")
        emit(f"{ind}for w in range(B):")
        i2 = ind + "    "
        emit(f"{i2}af = 1.0 if fn <= {R['lim']} else 0.0")
        emit(f"{i2}afw = af * wt  # no absorbed work in step 0 (adds an exact 0)")
        emit(f"{i2}dtw = {R['dt']}")
        for k, (_, c) in enumerate(loads):  # load scales: time curves at t = n dt (0 outside the curve)
            if c < 0:
                emit(f"{i2}sc{k} = 1.0")
                continue
            time_curve(i2, f"sc{k}", c, "fn * dtw")
        if D > 1:
            emit(f"{i2}{R['crushed']} = -1.0")
        # the reference walks the springs in order; 2-D's "first collapsed spring" needs that order
        for s in range(S):
            if mat[s] == GENERAL:
                emit(f"{i2}F{s} = {R[f'F{s}']}")
                emit(f"{i2}e{s} = {R[f'E{s}']}")
                if D > 1:
                    for d in range(D):
                        emit(f"{i2}ax{s}_{d} = {R[f'ax{s}_{d}']}")
                    emit(f"{i2}{R['crushed']} = {float(s)!r} if ({R[f'rev{s}']} >= 2.0 and {R['crushed']} < 0.0)"
                         f" else {R['crushed']}")  # fmt: skip
                if s in knotted:
                    knot_post(i2, s, R[f"gkc{s}"], R[f"gkx{s}"], R[f"gky{s}"], R[f"gksh{s}"])
                continue
            geometry(i2, [s], False)
            k = mat[s]
            if k == LINEAR:
                emit(f"{i2}F{s} = {R[f'kp{s}']} * e{s}")
            elif k == DAMPER:
                emit(f"{i2}F{s} = {R[f'kp{s}']} * {edot(s)}")
            elif k == NONLINEAR:
                emit(f"{i2}F{s} = {ramp(ca[s], f'e{s}')}")
                if s in knotted:  # the whole path
                    ep = R[f"ep{s}"]
                    knot_search(i2, s, f"_min({ep}, e{s})", f"_max({ep}, e{s})", "0.0", ep, ("kc", "kx", "ky"))
                    knot_post(i2, s, "kc", "kx", "ky", "0.0")
            elif k == CRUSH:
                emin, fstar = R[f"st{s}_0"], R[f"st{s}_1"]
                emit(f"{i2}emin = {emin}")
                emit(f"{i2}fstar = {fstar}")
                emit(f"{i2}on = e{s} <= emin")
                emit(f"{i2}f_load = _min(0.0, {ramp(ca[s], f'e{s}')})")
                emit(f"{i2}f_unl = _min(0.0, fstar + {R[f'kp{s}']} * (e{s} - emin))")
                emit(f"{i2}F{s} = f_load if on else f_unl")
                emit(f"{i2}{emin} = e{s} if on else emin")
                emit(f"{i2}{fstar} = f_load if on else fstar")
                if s in knotted:  # (e, e_min before the step): crushing further
                    knot_search(i2, s, f"e{s}", "emin", "0.0", R[f"ep{s}"], ("kc", "kx", "ky"))
                    knot_post(i2, s, "kc", "kx", "ky", "0.0")
            else:  # pragma: no cover - the compiler knows no other material
                raise ValueError(f"material code {k}")
        # summaries in spring order (the reference kernel's order of operations)
        emit(f"{i2}ie_tot = 0.0")
        for s in range(S):
            ie = R[f"ie{s}"]
            emit(f"{i2}{ie} = {ie} + (0.5 * (F{s} + {R[f'fp{s}']}) * (e{s} - {R[f'ep{s}']})) * afw")
            emit(f"{i2}ie_tot = ie_tot + {ie}")
            emit(f"{i2}{R[f'pf{s}']} = _max({R[f'pf{s}']}, abs(F{s}) * af)")
            emit(f"{i2}{R[f'mc{s}']} = _max({R[f'mc{s}']}, -e{s} * af)")
            emit(f"{i2}{R[f'fp{s}']} = F{s}")
            emit(f"{i2}{R[f'ep{s}']} = e{s}")
            if hist and D > 1:
                for d in range(D):
                    emit(f"{i2}{R[f'axh{s}_{d}']} = ax{s}_{d}")
        # nodal forces in the reference scatter's order, then the central-difference update
        emit(f"{i2}ke = 0.0")
        if ext:
            emit(f"{i2}bal = 0.0")
        for wl in range(W):
            emit(f"{i2}wf{wl} = 0.0")
        for n in live:
            for d in range(D):
                chain = _chain(n, d, lambda s: f"F{s}", lambda s, d: f"ax{s}_{d}")
                fext = f"{R[f'm{n}']} * {R[f'g{d}']}" if grav else "0.0"
                if n in loaded:  # gravity, then the loads on this node in load order
                    for k, (p, _) in enumerate(loads):
                        if p == n:
                            fext = f"({fext} + {R[f'lf{k}_{d}']} * sc{k})"
                    emit(f"{i2}fx_{d} = {fext}")
                    fext = f"fx_{d}"
                emit(f"{i2}fs = {chain}")
                emit(f"{i2}a = (fs + {fext}) * {R[f'im{n}_{d}']}")
                emit(f"{i2}vo_{d} = {R[f'v{n}_{d}']}")
                emit(f"{i2}vn_{d} = vo_{d} + (h * dtw) * a")
                for k, (p, dd, kind, c) in enumerate(pm):  # prescribed motion of this dof, in order
                    if (p, dd) != (n, d):
                        continue
                    sc = R[f"pms{k}"]
                    if kind == PM_DISPLACEMENT:
                        time_curve(i2, "tc", c, "fn * dtw + dtw")
                        emit(f"{i2}vn_{d} = (({R[f'x0{n}_{d}']} + {sc} * tc) - {R[f'x{n}_{d}']}) / dtw")
                    elif kind == PM_ACCELERATION:
                        time_curve(i2, "tc", c, "fn * dtw")
                        emit(f"{i2}vn_{d} = vo_{d} + (h * dtw) * {sc} * tc")
                    else:
                        time_curve(i2, "tc", c, "fn * dtw + 0.5 * dtw")
                        emit(f"{i2}vn_{d} = {sc} * tc")
                    pa = R[f"pma{k}"]
                    emit(f"{i2}last = fn == {R['nst']}  # the last step continues with the previous acceleration")
                    emit(f"{i2}{pa} = {pa} if last else (vn_{d} - vo_{d}) / (h * dtw)")
                    emit(f"{i2}vn_{d} = vo_{d} + (h * dtw) * {pa} if last else vn_{d}")
                    emit(f"{i2}a = {pa}")
                    emit(f"{i2}fx_{d} = fx_{d} + ({R[f'm{n}']} * a - (fs + fx_{d}))")
                emit(f"{i2}a_{d} = a")
                if n in loaded:  # external work: trapezoid with the previous step's force (R fx)
                    emit(f"{i2}vb = 0.5 * ({R[f'v0{n}_{d}']} + vo_{d}) if n1 else vo_{d}")
                    emit(f"{i2}bal = bal + 0.5 * (fx_{d} * vo_{d} + {R[f'fx{n}_{d}']} * vb)")
                    emit(f"{i2}{R[f'fx{n}_{d}']} = fx_{d}")
                elif grav:  # external work of gravity: trapezoid, f_ext^0 over the first half step
                    emit(f"{i2}vb = 0.5 * ({R[f'v0{n}_{d}']} + vo_{d}) if n1 else vo_{d}")
                    emit(f"{i2}bal = bal + 0.5 * (({fext}) * vo_{d} + (({fext}) * wt) * vb)")
                if n in keep_a:  # a^{n-1}: dampers' velocity estimate, knot crossings (R ao)
                    emit(f"{i2}{R[f'ao{n}_{d}']} = {R[f'a{n}_{d}']}")
                    emit(f"{i2}{R[f'a{n}_{d}']} = a")
            for wl in range(W):  # rigid walls, in wall order: land on the plane, no velocity into it
                if n not in walls[wl]:
                    continue
                nr = [R[f"wn{wl}_{d}"] for d in range(D)]
                pt = [R[f"wp{wl}_{d}"] for d in range(D)]
                xw = [R[f"x{n}_{d}"] for d in range(D)]
                emit(f"{i2}wv = {_lsum([f'vn_{d} * {nr[d]}' for d in range(D)])}")
                emit(f"{i2}gap = {_lsum([f'({xw[d]} - {pt[d]}) * {nr[d]}' for d in range(D)])}")
                emit(f"{i2}dist = {_lsum([f'(({xw[d]} + dtw * vn_{d}) - {pt[d]}) * {nr[d]}' for d in range(D)])}")
                emit(f"{i2}dvn = (-gap / dtw - wv) if ((dist < 0.0) & (wv < 0.0)) else 0.0")
                emit(f"{i2}we = 0.0")
                for d in range(D):
                    jp = R[f"jp{wl}_{n}_{d}"]
                    emit(f"{i2}jmp = dvn * {nr[d]} * {float(free[n][d])!r}")
                    emit(f"{i2}vn_{d} = vn_{d} + jmp")
                    emit(f"{i2}we = we + vo_{d} * (jmp + {jp})")
                    emit(f"{i2}{jp} = jmp")
                emit(f"{i2}we{wl}_{n} = -0.5 * {R[f'm{n}']} * we")
                emit(f"{i2}wf{wl} = wf{wl} + {R[f'm{n}']} * abs(dvn) / dtw")
            for d in range(D):
                x, v = R[f"x{n}_{d}"], R[f"v{n}_{d}"]
                emit(f"{i2}ke = ke + 0.5 * {R[f'm{n}']} * vo_{d} * vn_{d}")
                emit(f"{i2}{x} = {x} + (dtw * af) * vn_{d}")
                emit(f"{i2}{v} = vn_{d} * af + vo_{d} * (1.0 - af)")
            if movable[n]:
                a2 = _lsum([f"a_{d} * a_{d}" for d in range(D)])
                emit(f"{i2}{R[f'pa{n}']} = _max({R[f'pa{n}']}, {a2} * af)")
        if W:  # wall work in the reference's order (wall by wall, node by node), running variants only
            emit(f"{i2}wall_e = {R['wall_e']}")
            for wl in range(W):
                for n in walls[wl]:
                    if not static[n]:
                        emit(f"{i2}wall_e = wall_e + we{wl}_{n} if af > 0.0 else wall_e")
                emit(f"{i2}{R[f'pw{wl}']} = _max({R[f'pw{wl}']}, wf{wl} * af)")
                if "wall_force" in hist:
                    emit(f"{i2}{R[f'wf{wl}']} = wf{wl}")
            emit(f"{i2}{R['wall_e']} = wall_e")
        emit(f"{i2}ke = ke if wt > 0.0 else {R['ke0']}")
        if ext:
            emit(f"{i2}work = {R['work']} + (bal * dtw) * afw")
            emit(f"{i2}{R['work']} = work")
            emit(f"{i2}wmax = _max({R['wmax']}, abs(work))")
            emit(f"{i2}{R['wmax']} = wmax")
            emit(f"{i2}bal = abs((((ke + ie_tot) + {'wall_e' if W else '0.0'}) - {R['ke0']}) - work)")
            emit(f"{i2}thr = unstable_energy * ({R['ke0']} + wmax) + {R['efl']}")
        else:
            emit(f"{i2}bal = abs((((ke + ie_tot) + {'wall_e' if W else '0.0'}) - {R['ke0']}) - 0.0)")
            emit(f"{i2}thr = {R['thr']}")
        emit(f"{i2}{R['err']} = _max({R['err']}, bal * af)")
        emit(f"{i2}{R['thr']} = thr")
        bad = "not (bal <= thr)"
        if D > 1:
            bad = f"({bad} or {R['crushed']} >= 0.0)"
        emit(f"{i2}nbad += (1 if af > 0.0 else 0) if {bad} else 0")
        emit(f"{i2}{R['ken']} = ke")
        emit(f"{i2}{R['ien']} = ie_tot")
        if term:  # early termination (docs/format.md): decided for running lanes after the failure check
            emit(f"{i2}edmin = np.inf")
            for s in range(S):
                emit(f"{i2}edmin = _min(edmin, {R[f'ed{s}'] if mat[s] == GENERAL else edot(s)})")
            emit(f"{i2}fsum = {_lsum([f'abs(F{s})' for s in range(S)])}")
            emit(f"{i2}psum = {_lsum([R[f'pf{s}'] for s in range(S)])}")
            emit(f"{i2}kef = {R['kef']}")
            emit(f"{i2}small_f = fsum <= kef * psum")
            emit(f"{i2}small_ke = ke <= kef * ({R['ke0']} + {R['wmax'] if ext else '0.0'})")
            emit(f"{i2}opening = " + ("False" if ext else "edmin >= 0.0"))
            emit(f"{i2}stop = (wt > 0.0) & (kef > 0.0) & (not (fn * dtw < {R['tmin']})) & small_f & (small_ke | opening)")
            emit(f"{i2}{R['stop']} = 1.0 if stop else 0.0")
            emit(f"{i2}nstop += 1 if stop else 0")

    def _chain(n: int, d: int, force: Any, axis: Any) -> str:
        """Nodal force on dof (n, d) in the reference scatter's order: f[i] += F ax, f[j] -= F ax."""
        out = "0.0"
        for s in range(S):
            for side, op in ((si[s], "+"), (sj[s], "-")):
                if side != n:
                    continue
                term = force(s)
                if D > 1:
                    out = f"({out} {op} {term} * {axis(s, d)})"
                elif sign[s] == 0:
                    out = f"({out} {op} {term} * {R[f'sg{s}']})"
                else:  # a - b == a + (-b): the sign folds into the operator exactly
                    out = f"({out} {op if sign[s] == 1 else ('-' if op == '+' else '+')} {term})"
        return out

    def emit_results(ind: str) -> None:
        """Write lane w's summaries to its variant's columns (the lane's variant has ended)."""
        emit(f"{ind}q = vi[w]")
        wm = R["wmax"] if ext else "0.0"
        emit(f"{ind}energy_error[q] = {R['err']} / max({R['ke0']} + {wm}, 1e-300)")
        emit(f"{ind}if status[q] == 0:")
        emit(f"{ind}    t_end[q] = int({R['lim']}) * {R['dt']}")
        emit(f"{ind}elif n_fail[w] > 0:")
        emit(f"{ind}    t_end[q] = (n_fail[w] - 1) * {R['dt']}")
        for s in range(S):
            emit(f"{ind}absorbed[{s}, q] = {R[f'ie{s}']}")
            emit(f"{ind}peak_force[{s}, q] = {R[f'pf{s}']}")
            emit(f"{ind}max_crush[{s}, q] = {R[f'mc{s}']}")
        for n in range(N):
            emit(f"{ind}peak_acc[{n}, q] = " + ("0.0" if static[n] or not movable[n] else f"np.sqrt({R[f'pa{n}']})"))
        for wl in range(W):
            emit(f"{ind}peak_wall[{wl}, q] = {R[f'pw{wl}']}")

    head = [
        '"""Generated by crashstudy.kernel.generated (do not edit): one model shape, see _SHAPE."""',
        "import numba as nb",
        "import numpy as np",
        "from crashstudy.kernel.generated import reverse_yield_lane",
        "from crashstudy.kernel.scalar import knot_peak",
        "",
        f"_SHAPE = {shape!r}",
        "",
        "",
        '@nb.njit(inline="always", error_model="numpy")',
        "def _max(a, b):",
        "    return b if b > a else a",
        "",
        "",
        '@nb.njit(inline="always", error_model="numpy")',
        "def _min(a, b):",
        "    return b if b < a else a",
        "",
        "",
        '@nb.njit(nogil=True, error_model="numpy", cache=True)',
        "def run_blocks(b_lo, b_hi, starts, n_out, cst, mass, inv_mass, x0, v0, sign, length0, kpar, yield_t,",
        "               yield_c, cx, cy, cds, cs0, cs1, off, knot_y, gravity, dt, n_steps, out_every, invalid, e_floor,",
        "               unstable_energy, ke_fraction, min_time, wall_point, wall_normal, h_wall, peak_wall, load_force,",
        "               pm_scale, h_pos, h_disp, h_vel, h_acc, h_force, h_elong, h_energy, status, fail_time,",
        "               fail_item, t_end, peak_force, max_crush, absorbed, peak_acc, energy_error, final_energy):",
        *[f"    {cname[nm]} = cst[{i}]" for i, nm in enumerate(cname)],
        "    for bi in range(b_lo, b_hi):",
        "        lo = starts[bi]",
        "        B = starts[bi + 1] - lo",
        "        Z = np.zeros(NROWS * ROW)",
    ]
    L.extend(head)
    ind = "        "
    for s in general:
        emit(f"{ind}gst{s} = Z[{gs_row[s] * ROW}:{(gs_row[s] + 8) * ROW}].reshape((8, ROW))")
    emit(f"{ind}next_rec = np.zeros(B, dtype=np.int64)")
    emit(f"{ind}n_fail = np.full(B, -1, dtype=np.int64)")
    emit(f"{ind}vi = np.arange(lo, lo + B)  # the variant of each lane (lanes are compacted as variants end)")
    emit(f"{ind}nmax = -1")
    emit(f"{ind}for w in range(B):")
    i2 = ind + "    "
    emit(f"{i2}q = lo + w")
    if term:
        emit(f"{i2}{R['kef']} = ke_fraction[q]")
        emit(f"{i2}{R['tmin']} = min_time[q]")
    for n in range(N if D > 1 else 0):
        if static[n]:
            for d in range(D):
                emit(f"{i2}{R[f'xs{n}_{d}']} = x0[{n}, {d}, q]")
    emit(f"{i2}{R['dt']} = dt[q]")
    emit(f"{i2}{R['efl']} = e_floor[q]")
    for d in range(D if grav else 0):
        emit(f"{i2}{R[f'g{d}']} = gravity[{d}, q]")
    for k in range(len(loads)):
        for d in range(D):
            emit(f"{i2}{R[f'lf{k}_{d}']} = load_force[{k}, {d}, q]")
    for k in range(len(pm)):
        emit(f"{i2}{R[f'pms{k}']} = pm_scale[{k}, q]")
    if pm:
        emit(f"{i2}{R['nst']} = float(n_steps[q])")
    for c in tcurves:
        if c not in const:
            emit(f"{i2}{R[f'cx{off[c + 1] - 1}']} = cx[{off[c + 1] - 1}, q]")
    for wl in range(W):
        for d in range(D):
            emit(f"{i2}{R[f'wn{wl}_{d}']} = wall_normal[{wl}, {d}, q]")
            emit(f"{i2}{R[f'wp{wl}_{d}']} = wall_point[{wl}, {d}, q]")
    for n in live:
        emit(f"{i2}{R[f'm{n}']} = mass[{n}, q]")
        for d in range(D):
            emit(f"{i2}{R[f'x{n}_{d}']} = x0[{n}, {d}, q]")
            emit(f"{i2}{R[f'x0{n}_{d}']} = x0[{n}, {d}, q]")
            emit(f"{i2}{R[f'v{n}_{d}']} = v0[{n}, {d}, q]")
            emit(f"{i2}{R[f'im{n}_{d}']} = inv_mass[{n}, {d}, q]")
            if ext:
                emit(f"{i2}{R[f'v0{n}_{d}']} = v0[{n}, {d}, q]")
    for c in curves:
        if c in const:
            continue
        a0 = off[c]
        emit(f"{i2}{R[f'cy0_{c}']} = cy[{a0}, q]")
        emit(f"{i2}{R[f's0_{c}']} = cs0[{c}, q]")
        for k in range(a0, off[c + 1] - 1):
            emit(f"{i2}{R[f'cx{k}']} = cx[{k}, q]")
            if k > a0:
                emit(f"{i2}{R[f'ds{k}']} = cds[{k}, q]")
            if k in kcheck:
                emit(f"{i2}{R[f'kyv{k}']} = knot_y[{k}, q]")
    for s in range(S):
        emit(f"{i2}{R[f'kp{s}']} = kpar[{s}, q]")
        if D == 1:
            emit(f"{i2}{R[f'sg{s}']} = sign[{s}, q]")
        else:
            emit(f"{i2}{R[f'l0{s}']} = length0[{s}, q]")
            for d in range(D):
                emit(f"{i2}{R[f'ap{s}_{d}']} = x0[{sj[s]}, {d}, q] - x0[{si[s]}, {d}, q]")
    for s in general:
        emit(f"{i2}{R[f'yt{s}']} = yield_t[{s}, q]")
        emit(f"{i2}{R[f'yc{s}']} = yield_c[{s}, q]")
    emit(f"{i2}ke0 = 0.0")
    for n in range(N):  # every node, as the reference sums
        for d in range(D):
            emit(f"{i2}ke0 += 0.5 * mass[{n}, q] * v0[{n}, {d}, q] * v0[{n}, {d}, q]")
    emit(f"{i2}{R['ke0']} = ke0")
    emit(f"{i2}{R['thr']} = unstable_energy * (ke0 + 0.0) + e_floor[q]")
    emit(f"{i2}if invalid[q] > 0:")
    emit(f"{i2}    status[q] = 3")
    emit(f"{i2}    fail_item[q] = invalid[q]")
    emit(f"{i2}    fail_time[q] = 0.0")
    emit(f"{i2}    {R['lim']} = -1.0")
    emit(f"{i2}else:")
    emit(f"{i2}    {R['lim']} = float(n_steps[q])")
    emit(f"{i2}    nmax = max(nmax, n_steps[q])")
    emit(f"{ind}alive = nmax")
    emit(f"{ind}n_end = _next_end(Z, B, -1.0)")
    emit(f"{ind}next_min = 0")
    emit(f"{ind}ended = False")
    emit(f"{ind}for n in range(nmax + 1):")
    i3 = ind + "    "
    emit(f"{i3}if n > alive:")
    emit(f"{i3}    break")
    emit(f"{i3}fn = float(n)")
    emit(f"{i3}h = 1.0 if n > 0 else 0.5")
    emit(f"{i3}wt = 1.0 if n > 0 else 0.0")
    emit(f"{i3}n1 = n == 1")
    if general:
        pass_a(i3)
    if hist:  # a sample keeps x^n and v^{n-1/2}; the rest is read back after the pass
        emit(f"{i3}rec = n == next_min")
        emit(f"{i3}if rec:")
        emit(f"{i3}    for w in range(B):")
        for n in live:
            for d in range(D):
                emit(f"{i3}        {R[f'xh{n}_{d}']} = {R[f'x{n}_{d}']}")
                emit(f"{i3}        {R[f'vh{n}_{d}']} = {R[f'v{n}_{d}']}")
    pass_b(i3)
    if knotted:
        pass_k(i3)
    # failures (rare): the lanes whose energy balance broke (or, in 2-D, whose spring collapsed) stop here
    emit(f"{i3}if nbad > 0:")
    emit(f"{i3}    for w in range(B):")
    emit(f"{i3}        if not fn <= {R['lim']}:")
    emit(f"{i3}            continue")
    bal_expr = (f"abs(((({R['ken']} + {R['ien']}) + {R['wall_e'] if W else '0.0'}) - {R['ke0']}) - "
                + (R["work"] if ext else "0.0") + ")")  # fmt: skip
    emit(f"{i3}        if not ({bal_expr} <= {R['thr']}):")
    emit(f"{i3}            status[vi[w]] = 1")
    if D > 1:
        emit(f"{i3}        elif {R['crushed']} >= 0.0:")
        emit(f"{i3}            status[vi[w]] = 2")
        emit(f"{i3}            fail_item[vi[w]] = int({R['crushed']})")
    emit(f"{i3}        else:")
    emit(f"{i3}            continue")
    emit(f"{i3}        fail_time[vi[w]] = n * {R['dt']}")
    emit(f"{i3}        n_fail[w] = n")
    emit(f"{i3}        {R['lim']} = -1.0")
    emit(f"{i3}    alive = -1")
    emit(f"{i3}    for w in range(B):")
    emit(f"{i3}        alive = max(alive, int({R['lim']}))")
    emit(f"{i3}    n_end = _next_end(Z, B, fn - 1.0)")
    emit(f"{i3}    ended = True")
    if hist:
        emit(f"{i3}if rec:")
        emit(f"{i3}    next_min = nmax + 1")
        emit(f"{i3}    for w in range(B):")
        emit(f"{i3}        q = vi[w]")
        emit(f"{i3}        if fn > {R['lim']}:")
        emit(f"{i3}            continue")
        emit(f"{i3}        if n == next_rec[w]:")
        emit(f"{i3}            r = n // out_every[q]")
        emit(f"{i3}            next_rec[w] = n + out_every[q]")
        emit(f"{i3}            if r < n_out:")
        i5 = i3 + "                "
        for n in range(N):
            for d in range(D):
                if static[n]:
                    pos, dsp, vel, acc = f"x0[{n}, {d}, q]", "0.0", "0.0", "0.0"
                else:
                    pos = R[f"xh{n}_{d}"]
                    dsp = f"{R[f'xh{n}_{d}']} - {R[f'x0{n}_{d}']}"
                    # v^{n+1/2} is the lane's v row now (it ran: vn * 1.0 + vo * 0.0)
                    vel = f"(0.5 * ({R[f'vh{n}_{d}']} + {R[f'v{n}_{d}']}) if n > 0 else {R[f'vh{n}_{d}']})"
                    chain = _chain(n, d, lambda s: R[f"fp{s}"], lambda s, d: R[f"axh{s}_{d}"])
                    fext = f"{R[f'm{n}']} * {R[f'g{d}']}" if grav else "0.0"
                    fext = R[f"fx{n}_{d}"] if n in loaded else fext  # this step's external force
                    acc = f"({chain} + {fext}) * {R[f'im{n}_{d}']}"
                    for k, (p, dd, _, _) in enumerate(pm):  # a prescribed dof: its kinematic acceleration
                        if (p, dd) == (n, d):
                            acc = R[f"pma{k}"]
                for name, arr, val in (("position", "h_pos", pos), ("displacement", "h_disp", dsp),
                                       ("velocity", "h_vel", vel), ("acceleration", "h_acc", acc)):  # fmt: skip
                    if name in hist:
                        emit(f"{i5}{arr}[r, {n}, {d}, q] = {val}")
        for s in range(S):
            if "spring_force" in hist:
                emit(f"{i5}h_force[r, {s}, q] = {R[f'fp{s}']}")
            if "spring_elongation" in hist:
                emit(f"{i5}h_elong[r, {s}, q] = {R[f'ep{s}']}")
        if "kinetic_energy" in hist:
            emit(f"{i5}h_energy[r, 0, q] = {R['ken']}")
            emit(f"{i5}h_energy[r, 1, q] = {R['ien']}")
            emit(f"{i5}h_energy[r, 2, q] = {R['work'] if ext else '0.0'}")
            emit(f"{i5}h_energy[r, 3, q] = {R['wall_e'] if W else '0.0'}")
        for wl in range(W if "wall_force" in hist else 0):
            emit(f"{i5}h_wall[r, {wl}, q] = {R[f'wf{wl}']}")
        emit(f"{i3}        if fn + 1.0 <= {R['lim']}:")
        emit(f"{i3}            next_min = min(next_min, next_rec[w])")
    if term:  # lanes that met the termination test (and did not fail) end at this step
        emit(f"{i3}if nstop > 0:")
        emit(f"{i3}    for w in range(B):")
        emit(f"{i3}        if {R['stop']} > 0.0 and fn <= {R['lim']}:")
        emit(f"{i3}            {R['lim']} = fn")
        emit(f"{i3}            n_end = fn")
        emit(f"{i3}    alive = -1")
        emit(f"{i3}    for w in range(B):")
        emit(f"{i3}        alive = max(alive, int({R['lim']}))")
    emit(f"{i3}if fn == n_end:")
    emit(f"{i3}    for w in range(B):")
    emit(f"{i3}        if fn == {R['lim']}:")
    emit(f"{i3}            final_energy[0, vi[w]] = {R['ken']}")
    emit(f"{i3}            final_energy[1, vi[w]] = {R['ien']}")
    emit(f"{i3}            final_energy[2, vi[w]] = {R['work'] if ext else '0.0'}")
    emit(f"{i3}            final_energy[3, vi[w]] = {R['wall_e'] if W else '0.0'}")
    emit(f"{i3}    n_end = _next_end(Z, B, fn)")
    emit(f"{i3}    ended = True")
    # lanes whose variant ended leave the block once they are an eighth of it: their results are
    # written now and the running lanes move down, so later steps run over fewer lanes
    emit(f"{i3}if ended:")
    emit(f"{i3}    ended = False")
    emit(f"{i3}    gone = 0")
    emit(f"{i3}    for w in range(B):")
    emit(f"{i3}        gone += 1 if fn + 1.0 > {R['lim']} else 0")
    emit(f"{i3}    if gone >= max(8, B // 8) and gone < B:")
    emit(f"{i3}        k = 0")
    emit(f"{i3}        for w in range(B):")
    emit(f"{i3}            if fn + 1.0 > {R['lim']}:")
    emit_results(i3 + "                ")
    emit(f"{i3}                continue")
    emit(f"{i3}            if k != w:")
    emit(f"{i3}                for r in range(NROWS):")
    emit(f"{i3}                    Z[r * ROW + k] = Z[r * ROW + w]")
    emit(f"{i3}                vi[k] = vi[w]")
    emit(f"{i3}                next_rec[k] = next_rec[w]")
    emit(f"{i3}                n_fail[k] = n_fail[w]")
    emit(f"{i3}            k += 1")
    emit(f"{i3}        B = k")
    emit(f"{i3}        n_end = _next_end(Z, B, fn)")
    if hist:
        emit(f"{i3}        next_min = nmax + 1")
        emit(f"{i3}        for w in range(B):")
        emit(f"{i3}            next_min = min(next_min, next_rec[w])")
    # results of the block's remaining lanes
    emit(f"{ind}for w in range(B):")
    emit_results(ind + "    ")
    L.extend([
        "",
        "",
        '@nb.njit(inline="always", error_model="numpy")',
        "def _next_end(Z, B, after):",
        '    """The smallest step limit of a running lane above ``after`` (-1 if none)."""',
        "    out = np.inf",
        "    for w in range(B):",
        f"        lim = Z[{R.at['lim'] * ROW} + w]",
        "        if lim > after and lim < out:",
        "            out = lim",
        "    return out if out < np.inf else -1.0",
        "",
        "",
        f"NROWS = {R.n}",
        f"ROW = {ROW}",
        "",
    ])  # fmt: skip
    return "\n".join(L) + "\n"


_SOURCES: dict[str, tuple[str, str]] = {}  # repr(shape) -> (source, key)


def _source_key(shape: dict[str, Any]) -> tuple[str, str]:
    """A shape's source and its name (a hash of the source), generated once per process: the kernel
    choice, the compile check and the run all ask for it every chunk."""
    r = repr(shape)
    if r not in _SOURCES:
        src = _source(shape)
        _SOURCES[r] = (src, hashlib.sha256(src.encode()).hexdigest()[:20])
    return _SOURCES[r]


def _module(shape: dict[str, Any]) -> Any:
    """The compiled module for ``shape`` (generated, written and imported once per process)."""
    src, key = _source_key(shape)
    with _LOCK:
        if key in _LOADED:
            return _LOADED[key]
        folder = checked_dir()  # private to this user: numba unpickles what it finds there
        path = folder / f"k_{key}.py"
        if not path.exists() or path.read_text() != src:
            tmp = folder / f".k_{key}.{os.getpid()}.tmp"
            tmp.write_text(src)
            os.replace(tmp, path)
        name = f"crashstudy_generated_{key}"
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
        _LOADED[key] = mod
        return mod


def shape_key(shape: dict[str, Any]) -> str:
    """The name of a shape's kernel: a hash of its source."""
    return _source_key(shape)[1]


def is_compiled(b: Batch, histories: tuple[str, ...], vary: frozenset[int] | None = None) -> bool:
    """Whether this model shape's kernel is compiled: loaded in this process, or in numba's disk cache
    (wherever ``NUMBA_CACHE_DIR`` puts it; the index is written after the compiled code)."""
    shape = _shape(b, histories, vary)
    key = shape_key(shape)
    if key in _LOADED and _LOADED[key].run_blocks.signatures:
        return True
    if why_not_private(cache_dir()) is not None:
        return False
    try:
        mod = _module(shape)
        return bool(mod.run_blocks.signatures) or os.path.exists(mod.run_blocks._cache._cache_file._index_path)
    except Exception:  # numba internals moved: treat as not compiled
        return False


def run_generated(b: Batch, histories: tuple[str, ...], n_out: int, vary: frozenset[int] | None = None,
                  const: list[int] | None = None) -> KernelOutput:  # fmt: skip
    """Integrate every variant of ``b`` with its model's generated kernel (results bitwise those of
    the reference kernel). ``b`` must be supported (:func:`unsupported` returns None)."""
    why = unsupported(b)
    if why is not None:
        raise ValueError(f"no generated kernel for this model: {why}")
    from crashstudy.kernel.reference import UNSTABLE_ENERGY

    shape = _shape(b, histories, vary, const)
    mod = _module(shape)
    N, D, V = b.x0.shape
    S = len(b.spring_i)
    out = allocate(S, N, D, b.wall_nodes.shape[0], V, histories, n_out)
    want_energy = any(h in histories for h in ENERGIES)
    h_energy = np.full((n_out, 4, V), np.nan) if want_energy else np.empty((1, 4, 1))

    def buf(name: str, nd: int) -> np.ndarray:
        return out.histories[name] if name in out.histories else np.empty((1,) * nd)

    starts = np.unique(np.minimum(np.arange(0, V + BLOCK, BLOCK), V)).astype(np.int64)
    args = (starts, n_out, _constants(b, shape), b.mass, b.inv_mass, b.x0, b.v0, b.sign, b.length0, b.kpar,
            b.yield_t, b.yield_c, b.cx, b.cy, b.cds, b.cs0, b.cs1, b.curve_off, b.knot_y, b.gravity, b.dt, b.n_steps,
            b.out_every, b.invalid, b.energy_floor, UNSTABLE_ENERGY, b.ke_fraction, b.min_time, b.wall_point,
            b.wall_normal, buf("wall_force", 3), out.peak_wall_force, b.load_force, b.pm_scale, buf("position", 4), buf("displacement", 4), buf("velocity", 4),
            buf("acceleration", 4), buf("spring_force", 3), buf("spring_elongation", 3), h_energy, out.status,
            out.fail_time, out.fail_item, out.t_end, out.peak_force, out.max_crush, out.absorbed_energy,
            out.peak_acceleration, out.energy_error, out.final_energy)  # fmt: skip
    nblocks = len(starts) - 1
    threads = min(get_threads(), nblocks)
    if threads <= 1:
        mod.run_blocks(0, nblocks, *args)
    else:
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(lambda bi: mod.run_blocks(bi, bi + 1, *args), range(nblocks)))
    for k, name in enumerate(ENERGIES):
        if name in out.histories:
            out.histories[name][:] = h_energy[:, k, :]
    return out
