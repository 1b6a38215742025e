"""A model -> an LS-DYNA keyword deck of discrete elements (SPEC 8c; docs/dyna.md).

The deck runs the same model in LS-DYNA: nodes in 3-D (a 1-D model along x, with y, z and the
rotations held by ``*BOUNDARY_SPC_NODE``; a 2-D model in the x-y plane, z and rotations held), one
``*PART`` + ``*SECTION_DISCRETE`` + material per spring (:mod:`.dyna_materials`), curves in each
material's sign convention, time curves padded with zeros so that LS-DYNA's extrapolation gives
crashstudy's "zero outside its range". What LS-DYNA has no keyword for and that does not change the
motion (crashstudy ids, the time-step rule, the histories and crash criteria asked for) travels in
``$crashstudy:`` comment lines that LS-DYNA ignores and :mod:`.dyna_import` reads back, so export
then import gives a model whose results are identical. A feature with no keyword equivalent is
refused by name (:func:`refusals`), never dropped.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

from crashstudy.errors import InputError, Problem
from crashstudy.exchange.dyna_cards import LAYOUTS, Rounded, card, fmt_float, titles
from crashstudy.exchange.dyna_materials import BY_TYPE, crush_curve_out
from crashstudy.schema.model import Model
from crashstudy.schema.yamlio import LoadedYaml
from crashstudy.units import UNIT_SYSTEMS

META = "$crashstudy:"  #: prefix of the comment lines that carry what has no keyword
META_WIDTH = 80
PAD = 1.0e-9  #: relative width (of the curve's span) of the step down to zero that ends a padded time curve


def refusals(m: Model, doc: LoadedYaml | None) -> list[Problem]:
    """Features of ``m`` with no LS-DYNA keyword equivalent: one problem each, by name."""
    out: list[tuple[tuple[str | int, ...], str]] = []
    for sid, sp in m.springs.items():
        if sp.failure is not None:
            out.append(
                (
                    ("springs", sid, "failure"),
                    "spring failure has no discrete-element keyword equivalent "
                    "crashstudy can vouch for (*SECTION_DISCRETE CDL/TDL are deflection limits): remove failure: "
                    "to export, or model the break in LS-DYNA by hand",
                )
            )
        if sp.material.type not in BY_TYPE:
            out.append(
                (
                    ("springs", sid, "material", "type"),
                    f"material {sp.material.type!r} has no LS-DYNA "
                    f"mapping yet (exchange/dyna_materials.MATERIALS)",
                )
            )
    for i, w in enumerate(m.rigid_walls):
        if w.stiffness is not None:
            out.append(
                (
                    ("rigid_walls", i, "stiffness"),
                    "a penalty wall (stiffness) has no *RIGIDWALL_PLANAR "
                    "equivalent (its RWKSF scales LS-DYNA's own penalty): remove stiffness: for a stonewall",
                )
            )
    file = doc.file if doc is not None else m.name
    return [
        Problem(file, doc.line_of(path) if doc is not None else None, ".".join(map(str, path)), msg)
        for path, msg in out
    ]


@dataclass
class _Deck:
    """The deck under construction: ids, curves to write, and values rounded to fit their fields."""

    m: Model
    rounded: Rounded = field(default_factory=lambda: Rounded([]))
    lines: list[str] = field(default_factory=list)
    lcids: dict[tuple[str, str], int] = field(default_factory=dict)
    curve_cards: list[str] = field(default_factory=list)
    meta_curves: dict[str, list[Any]] = field(default_factory=dict)
    count: int = 0

    def add(self, keyword: str, *cards: str) -> None:
        self.lines.append(f"*{keyword}")
        self.lines.extend(cards)

    def lcid(self, curve: str, role: str) -> int:
        """LCID of ``curve`` in the sign convention ``role`` (written once per curve and role)."""
        key = (curve, role)
        if key not in self.lcids:
            self.lcids[key] = n = self._next()
            self._write_curve(n, curve, role)
        return self.lcids[key]

    def table(self, rows: list[dict[str, Any]]) -> int:
        """TBID of a ``*DEFINE_TABLE`` of ``[{rate, curve}, ...]`` (rates ascending), its curves right after it."""
        tbid = self._next()
        ids = [self._next() for _ in rows]
        self.curve_cards += [f"*DEFINE_TABLE\n{titles('DEFINE_TABLE')}", card("DEFINE_TABLE", {"TBID": tbid})]
        self.curve_cards += [
            card("DEFINE_TABLE_ROW", {"VALUE": r["rate"], "LCID": n}, self.rounded, "table rate")
            for r, n in zip(rows, ids, strict=True)
        ]
        for r, n in zip(rows, ids, strict=True):
            self._write_curve(n, r["curve"], "same")
        self.meta_curves[str(tbid)] = ["table", "table", 0, 0]
        return tbid

    def _next(self) -> int:  # curves and tables share one id space in LS-DYNA
        self.count += 1
        return self.count

    def curve(self, lcid: object, role: str, field: str) -> str:  # pragma: no cover - import side only
        raise NotImplementedError

    def is_table(self, lcid: object) -> bool:  # pragma: no cover - import side only
        return False

    def table_curves(
        self, tbid: object, field: str
    ) -> list[dict[str, Any]]:  # pragma: no cover - import side only
        raise NotImplementedError

    def _write_curve(self, n: int, cid: str, role: str) -> None:
        if (
            role == "constant"
        ):  # a constant load or gravity (1.0), or the step cap (dt): from t = 0 to past end_time
            value = self.m.time_step.dt if cid == "time_step.dt" and self.m.time_step.dt else 1.0
            xs, ys, pads = [0.0, 2.0 * self.m.end_time], [value, value], [0, 0]
        else:
            c = self.m.curves[cid]
            xs, ys = list(c.x), list(c.y)
            if role == "crush":
                xs, ys = crush_curve_out(xs, ys)
            pads = [0, 0]
            if role == "time":
                xs, ys, pads = _pad_time(xs, ys)
        self.meta_curves[str(n)] = [cid, role, *pads]
        what = f"curves.{cid}" if role != "constant" else "constant curve"
        self.curve_cards.append(f"*DEFINE_CURVE\n$ {role} curve {cid}\n{titles('DEFINE_CURVE')}")
        self.curve_cards.append(card("DEFINE_CURVE", {"LCID": n, "SIDR": 0, "SFA": 1.0, "SFO": 1.0}))
        self.curve_cards.extend(
            card("DEFINE_CURVE_POINT", {"A": x, "O": y}, self.rounded, what)
            for x, y in zip(xs, ys, strict=True)
        )


def _pad_time(xs: list[float], ys: list[float]) -> tuple[list[float], list[float], list[int]]:
    """A time curve that reads zero outside its range under constant or linear extrapolation."""
    span = xs[-1] - xs[0]
    head: list[tuple[float, float]] = []
    tail: list[tuple[float, float]] = []
    if xs[0] > 0.0 and (ys[0] != 0.0 or ys[1] != 0.0):
        head = (
            [(xs[0] - PAD * span - span, 0.0), (xs[0] - PAD * span, 0.0)]
            if ys[0] != 0.0
            else [(xs[0] - span, 0.0)]
        )
    if ys[-1] != 0.0:
        tail = [(xs[-1] + PAD * span, 0.0), (xs[-1] + PAD * span + span, 0.0)]
    elif ys[-2] != 0.0:
        tail = [(xs[-1] + span, 0.0)]
    head = [(_short(x), y) for x, y in head]  # where the step sits within PAD does not matter: a short text
    tail = [(_short(x), y) for x, y in tail]
    pts = head + list(zip(xs, ys, strict=True)) + tail
    return [p[0] for p in pts], [p[1] for p in pts], [len(head), len(tail)]


def _short(x: float) -> float:
    return float(fmt_float(x, LAYOUTS["DEFINE_CURVE_POINT"][0][1])[0])


def _meta_lines(meta: dict[str, Any]) -> list[str]:
    text = json.dumps(meta, separators=(",", ":"), ensure_ascii=True)
    step = META_WIDTH - len(META) - 1
    return [f"{META} {text[i : i + step]}" for i in range(0, len(text), step)]


def export_deck(m: Model, doc: LoadedYaml | None = None) -> tuple[str, list[str]]:
    """The keyword deck of ``m`` and the values that had to be rounded to fit their fields.

    Raises :class:`InputError` naming each feature with no keyword equivalent."""
    problems = refusals(m, doc)
    if problems:
        raise InputError(problems)
    d = _Deck(m)
    dim = len(next(iter(m.nodes.values())).position)
    nid = {n: i + 1 for i, n in enumerate(m.nodes)}
    units = UNIT_SYSTEMS[m.units]
    d.lines.append("*KEYWORD")
    d.add(
        "TITLE",
        f"{m.name} (crashstudy, units {m.units}: {units.length} {units.time} {units.mass} {units.force})"[
            :80
        ],
    )
    d.add(
        "CONTROL_TERMINATION",
        titles("CONTROL_TERMINATION"),
        card("CONTROL_TERMINATION", {"ENDTIM": m.end_time}, d.rounded, "end_time"),
    )
    ts = m.time_step
    if ts.safety_factor is not None:
        d.add(
            "CONTROL_TIMESTEP",
            card(
                "CONTROL_TIMESTEP",
                {"DTINIT": 0.0, "TSSFAC": ts.safety_factor},
                d.rounded,
                "time_step.safety_factor",
            ),
        )
    elif ts.dt is not None:  # LS-DYNA has no fixed step: the first step and a cap (LCTM) of dt
        cap = d.lcid("time_step.dt", "constant")
        d.add(
            "CONTROL_TIMESTEP",
            card(
                "CONTROL_TIMESTEP", {"DTINIT": ts.dt, "TSSFAC": 0.9, "LCTM": cap}, d.rounded, "time_step.dt"
            ),
        )
    d.add("NODE", titles("NODE"))
    for n, node in m.nodes.items():
        p = [*node.position, 0.0, 0.0][:3]
        d.lines.append(
            card("NODE", {"NID": nid[n], "X": p[0], "Y": p[1], "Z": p[2]}, d.rounded, f"nodes.{n}.position")
        )
    masses = [(n, node.mass) for n, node in m.nodes.items() if node.mass is not None]
    if masses:
        d.add("ELEMENT_MASS", titles("ELEMENT_MASS"))
        d.lines.extend(
            card("ELEMENT_MASS", {"EID": i + 1, "NID": nid[n], "MASS": mass}, d.rounded, f"nodes.{n}.mass")
            for i, (n, mass) in enumerate(masses)
        )
    _constraints(d, nid, dim)
    _springs(d, nid)
    _loads(d, nid, dim)
    _walls(d, nid, dim)
    dt_out = m.output.interval or m.end_time / 1000
    for db in ("NODOUT", "DEFORC", "GLSTAT"):
        d.add(f"DATABASE_{db}", card("DATABASE", {"DT": dt_out}, d.rounded, "output.interval"))
    ids = list(nid.values())
    d.add(
        "DATABASE_HISTORY_NODE",
        *(
            card("DATABASE_HISTORY_NODE", {f"ID{k + 1}": v for k, v in enumerate(ids[i : i + 8])})
            for i in range(0, len(ids), 8)
        ),
    )
    meta = {
        "format": 1,
        "name": m.name,
        "description": m.description,
        "units": m.units,
        "nodes": list(m.nodes),
        "springs": list(m.springs),
        "walls": [[w.id, w.normal] for w in m.rigid_walls],
        "curves": d.meta_curves,
        **m.model_dump(
            include={"time_step", "output", "termination", "metrics", "accuracy_check"}, exclude_none=True
        ),
        "exact": d.rounded.restore_table(),
    }
    text = "\n".join([d.lines[0], *_meta_lines(meta), *d.lines[1:], *d.curve_cards, "*END"]) + "\n"
    return text, d.rounded.items


def _constraints(d: _Deck, nid: dict[str, int], dim: int) -> None:
    """SPC of fixed directions and of the directions the model does not use (z and rotations; y in 1-D)."""
    rows, velocities = [], []
    for n, node in d.m.nodes.items():
        fixed = ["x", "y"][:dim] if node.fixed is True else [] if node.fixed is False else list(node.fixed)
        dof = {
            "DOFX": int("x" in fixed),
            "DOFY": int("y" in fixed or dim == 1),
            "DOFZ": 1,
            "DOFRX": 1,
            "DOFRY": 1,
            "DOFRZ": 1,
        }
        rows.append(card("BOUNDARY_SPC_NODE", {"NID": nid[n], "CID": 0, **dof}))
        v = d.m.initial_velocity.get(n)
        if v is not None and any(v):
            vel = [*v, 0.0][:2]
            velocities.append(
                card(
                    "INITIAL_VELOCITY_NODE",
                    {"NID": nid[n], "VX": vel[0], "VY": vel[1], "VZ": 0.0},
                    d.rounded,
                    f"initial_velocity.{n}",
                )
            )
    if velocities:
        d.add("INITIAL_VELOCITY_NODE", titles("INITIAL_VELOCITY_NODE"), *velocities)
    d.add("BOUNDARY_SPC_NODE", titles("BOUNDARY_SPC_NODE"), *rows)


def _springs(d: _Deck, nid: dict[str, int]) -> None:
    """Per spring: *PART, *SECTION_DISCRETE (both cards), its material, *ELEMENT_DISCRETE."""
    elements = []
    for k, (sid, sp) in enumerate(d.m.springs.items(), start=1):
        mat = sp.material.model_dump(exclude_none=True)
        row = BY_TYPE[mat["type"]]
        d.add("PART", f"{sid}"[:70], card("PART", {"PID": k, "SECID": k, "MID": k}))
        d.add(
            "SECTION_DISCRETE",
            titles("SECTION_DISCRETE"),
            card("SECTION_DISCRETE", {"SECID": k, "DRO": 0, "KD": 0.0, "V0": 0.0, "CL": 0.0, "FD": 0.0}),
            titles("SECTION_DISCRETE_2"),
            card("SECTION_DISCRETE_2", {"CDL": 0.0, "TDL": 0.0}),
        )
        d.add(
            row.keyword,
            titles(row.keyword),
            card(row.keyword, {"MID": k, **row.write(mat, d)}, d.rounded, f"springs.{sid}.material"),
        )
        a, b = sp.nodes
        elements.append(
            card(
                "ELEMENT_DISCRETE",
                {
                    "EID": k,
                    "PID": k,
                    "N1": nid[a],
                    "N2": nid[b],
                    "VID": 0,
                    "S": 1.0,
                    "PF": 0,
                    "OFFSET": sp.initial_elongation,
                },
                d.rounded,
                f"springs.{sid}.initial_elongation",
            )
        )
    if elements:
        d.add("ELEMENT_DISCRETE", titles("ELEMENT_DISCRETE"), *elements)


def _loads(d: _Deck, nid: dict[str, int], dim: int) -> None:
    m = d.m
    for i, ld in enumerate(m.loads):
        lc = d.lcid(ld.curve, "time") if ld.curve else d.lcid(f"loads.{i}", "constant")
        for k, f in enumerate(ld.force):
            if f != 0.0 or (k == 0 and not any(ld.force)):
                d.add(
                    "LOAD_NODE_POINT",
                    card(
                        "LOAD_NODE_POINT",
                        {"NID": nid[ld.node], "DOF": k + 1, "LCID": lc, "SF": f},
                        d.rounded,
                        f"loads.{i}.force.{k}",
                    ),
                )
    if m.gravity is not None:  # LS-DYNA body loads are base accelerations: gravity -g is SF = +g
        lc = d.lcid("gravity", "constant")
        for k, g in enumerate(m.gravity):
            if g != 0.0:
                d.add(
                    f"LOAD_BODY_{'XY'[k]}",
                    card("LOAD_BODY", {"LCID": lc, "SF": -g}, d.rounded, f"gravity.{k}"),
                )
    vad = {"velocity": 0, "acceleration": 1, "displacement": 2}
    for i, q in enumerate(m.prescribed_motion):
        d.add(
            "BOUNDARY_PRESCRIBED_MOTION_NODE",
            titles("BOUNDARY_PRESCRIBED_MOTION_NODE"),
            card(
                "BOUNDARY_PRESCRIBED_MOTION_NODE",
                {
                    "NID": nid[q.node],
                    "DOF": "xy".index(q.direction) + 1,
                    "VAD": vad[q.quantity],
                    "LCID": d.lcid(q.curve, "time"),
                    "SF": q.scale,
                    "VID": 0,
                },
                d.rounded,
                f"prescribed_motion.{i}.scale",
            ),
        )


def _walls(d: _Deck, nid: dict[str, int], dim: int) -> None:
    """Stonewalls: *RIGIDWALL_PLANAR_ID (tail at the wall point, head at point + normal); listed nodes as a set."""
    for i, w in enumerate(d.m.rigid_walls, start=1):
        nsid = 0
        if w.nodes is not None:
            nsid = i
            ids = [nid[n] for n in w.nodes]
            d.add(
                "SET_NODE_LIST",
                card("SET_NODE_LIST", {"SID": nsid}),
                *(
                    card("SET_NODE_LIST_IDS", {f"NID{k + 1}": v for k, v in enumerate(ids[j : j + 8])})
                    for j in range(0, len(ids), 8)
                ),
            )
        p = [*w.point, 0.0, 0.0][:3]
        nv = [*w.normal, 0.0, 0.0][:3]
        head = [p[k] + nv[k] for k in range(3)]
        d.add(
            "RIGIDWALL_PLANAR_ID",
            card("RIGIDWALL_ID", {"ID": i, "TITLE": w.id}),
            card("RIGIDWALL_PLANAR", {"NSID": nsid, "NSIDEX": 0, "BOXID": 0, "OFFSET": 0.0}),
            card(
                "RIGIDWALL_PLANAR_2",
                {"XT": p[0], "YT": p[1], "ZT": p[2], "XH": head[0], "YH": head[1], "ZH": head[2]},
                d.rounded,
                f"rigid_walls.{i - 1}.point / normal",
            ),
        )
