"""Locals of a generated pass, each assigned once: the step's passes are unrolled per spring and node, and
reused short names (``kc``, ``th``, ``e``, ``a``...) once per spring or node. numba's SSA reconstruction
walks the whole function (every block, every statement) once for each variable assigned more than once,
so a pass's compile grew with (its length) x (its reused names); renamed, the same statements compute the
same numbers and the walk is skipped (benchmarks/results/generated_source.md, session 35).

Tried and dropped here (measured on the knots twin's ``_pass_b``): each row ``Z[k + w]`` read once into a
local (fewer getitems, but more named locals: SSA and lowering grew, the compile went up ~20 %); each row
as a 1-D view of a 2-D ``Z`` (LLVM took minutes); ``Z`` as a 2-D array indexed ``Z[r, w]`` (within noise).
"""

from __future__ import annotations

import re

# a plain assignment: targets (names and rows of Z, comma separated) = value
_ASSIGN = re.compile(r"^(?P<lhs>[\w\[\] +,]+?) = (?P<rhs>.*)$")
_HEADS = ("if ", "elif ", "else:", "for ", "while ", "return", "break", "continue")


_NAME = re.compile(r"\b[A-Za-z_]\w*\b")


def single_definitions(lines: list[str]) -> list[str]:
    """``lines`` (the body of a pass) with each local that a lane loop's body assigns more than once, in
    its straight-line part only, renamed at each assignment (``kc``, ``kc_r1``, ``kc_r2``...): the same
    values, but numba's SSA reconstruction, which walks the whole function once per variable defined
    twice, has fewer of them to walk for. A local is kept as it is when it is also assigned in a nested
    block, read before its first assignment in the body (carried from the lane before), or used outside
    the body."""
    out = list(lines)
    i = 0
    while i < len(out):
        if out[i].strip().startswith("for w_ in range("):
            head = len(out[i]) - len(out[i].lstrip())
            j = i + 1
            while j < len(out) and (not out[j].strip() or len(out[j]) - len(out[j].lstrip()) > head):
                j += 1
            out[i + 1 : j] = _rename(out[i + 1 : j], out[:i] + out[j:])
        i += 1
    return out


def _fresh(name: str, taken: set[str]) -> str:
    while name in taken:
        name += "_"
    taken.add(name)
    return name


def _code(ln: str) -> str:
    return ln.split("#", 1)[0]


def _rename(body: list[str], rest: list[str]) -> list[str]:
    """The lane loop ``body`` renamed (see :func:`single_definitions`); ``rest``: the function's other lines."""
    level = min(len(ln) - len(ln.lstrip()) for ln in body if ln.strip())
    defs: dict[str, int] = {}
    bad = {w for ln in rest for w in _NAME.findall(_code(ln))}
    seen: set[str] = set()
    for ln in body:
        text = _code(ln).strip()
        ind = len(ln) - len(ln.lstrip())
        m = _ASSIGN.match(text)
        if m is None or text.startswith(_HEADS):
            seen.update(_NAME.findall(text))
            if re.match(r"^\w+ *[-+*/|&]?= ", text):  # an augmented assignment (x += ...): keep x
                bad.add(text.split()[0])
            continue
        seen.update(_NAME.findall(m["rhs"]))
        for t in (t.strip() for t in m["lhs"].split(",")):
            if not re.fullmatch(r"\w+", t):
                seen.update(_NAME.findall(t))
                continue
            if ind != level or (t in seen and t not in defs):
                bad.add(t)
            defs[t] = defs.get(t, 0) + 1
            seen.add(t)
    names = {t for t, k in defs.items() if k > 1 and t not in bad}
    if not names:
        return body
    taken = bad | seen
    now = {t: t for t in names}
    count = dict.fromkeys(names, 0)
    word = re.compile(r"\b(" + "|".join(sorted(names, key=len, reverse=True)) + r")\b")
    out = []
    for ln in body:
        code, sep, note = ln.partition("#")
        text = code.strip()
        pre = code[: len(code) - len(code.lstrip())]
        m = _ASSIGN.match(text)
        if m is None or text.startswith(_HEADS) or len(pre) != level:
            out.append(word.sub(lambda r: now[r[1]], code) + sep + note)
            continue
        rhs = word.sub(lambda r: now[r[1]], m["rhs"])
        targets = []
        for t in (t.strip() for t in m["lhs"].split(",")):
            if t in names:
                now[t] = t if count[t] == 0 else _fresh(f"{t}_r{count[t]}", taken)
                count[t] += 1
                t = now[t]
            else:
                t = word.sub(lambda r: now[r[1]], t)
            targets.append(t)
        out.append(f"{pre}{', '.join(targets)} = {rhs}" + (f"  {sep}{note}" if sep else ""))
    return out
