"""A deck's initial velocities, constraints, loads and prescribed motion, rigid walls and controls -> the
model's fields (part of :func:`crashstudy.exchange.dyna_import.import_deck`).
"""

from __future__ import annotations

from typing import Any

from crashstudy.errors import Problem
from crashstudy.exchange.dyna_deck import Block
from crashstudy.exchange.dyna_reader import DeckReader, Rows

NEVER_TIME = 1.0e28  #: BIRTH/DEATH at or beyond this: "always" (LS-DYNA's default DEATH)


def read_boundary(
    r: DeckReader,
    model: dict[str, Any],
    rows: Rows,
    by: dict[str, list[Block]],
    nid_name: dict[int, str],
    dim: int,
) -> None:
    iv = {}
    for b, c, f in rows["INITIAL_VELOCITY_NODE"]:
        n = int(f["NID"] or 0)  # type: ignore[call-overload]
        if n not in nid_name:
            r.fail(b, f"NID {n}: no such node", c, "NID")
            continue
        iv[nid_name[n]] = [float(f[k] or 0.0) for k in ("VX", "VY")][:dim]  # type: ignore[arg-type]
    model["initial_velocity"] = iv
    loads: dict[tuple[int, int], list[float]] = {}
    for b, c, f in rows["LOAD_NODE_POINT"]:
        n, dof, lc = int(f["NID"] or 0), int(f["DOF"] or 0), int(f["LCID"] or 0)  # type: ignore[call-overload]
        if n not in nid_name or dof not in (1, 2)[:dim] or f["CID"] or lc == 0:
            r.fail(
                b,
                f"expected a node, DOF 1{' or 2' if dim == 2 else ''}, a load curve and CID 0; got NID {n}, "
                f"DOF {dof}, LCID {lc}",
                c,
                "DOF",
            )
            continue
        loads.setdefault((n, lc), [0.0] * dim)[dof - 1] += float(f["SF"] if f["SF"] is not None else 1.0)  # type: ignore[arg-type]
    model["loads"] = []
    for (n, lc), force in loads.items():
        info = r.meta.get("curves", {}).get(str(lc))
        r.where = (by["LOAD_NODE_POINT"][0], None)
        ld: dict[str, Any] = {"node": nid_name[n], "force": force}
        if not (info and info[1] == "constant"):
            ld["curve"] = r.curve(lc, "time", "LCID")
        model["loads"].append(ld)
    gravity = [0.0] * dim
    for k, axis in enumerate("XYZ"):
        for b in by.get(f"LOAD_BODY_{axis}", []):
            body = r.fields(b, b.cards[0], "LOAD_BODY") if b.cards else None
            if body is None:
                continue
            f = body
            lc = int(f["LCID"] or 0)  # type: ignore[call-overload]
            ys = r.curves_raw.get(lc, (b, [], []))[2]
            if k >= dim or not ys or min(ys) != max(ys) or any(f[x] for x in ("LCIDDR", "CID")):
                r.fail(
                    b,
                    "a body load must be constant in time (gravity) along a direction the model uses",
                    b.cards[0],
                )
                continue
            gravity[k] = -float(f["SF"] if f["SF"] is not None else 1.0) * ys[0]  # type: ignore[arg-type]
    if any(gravity):
        model["gravity"] = gravity
    motion = []
    for b, c, f in rows["BOUNDARY_PRESCRIBED_MOTION_NODE"]:
        n, dof, vad = int(f["NID"] or 0), int(f["DOF"] or 0), int(f["VAD"] or 0)  # type: ignore[call-overload]
        limits = [float(f[k]) for k in ("BIRTH", "DEATH") if f[k] is not None]  # type: ignore[arg-type]
        if (
            n not in nid_name
            or dof not in (1, 2)[:dim]
            or vad not in (0, 1, 2)
            or f["VID"]
            or any(0.0 < abs(v) < NEVER_TIME for v in limits)
        ):
            r.fail(
                b,
                f"expected a node, DOF 1{' or 2' if dim == 2 else ''}, VAD 0 (velocity), 1 (acceleration) or 2 "
                "(displacement), VID 0 and no BIRTH/DEATH times",
                c,
                "DOF",
            )
            continue
        r.where = (b, c)
        scale = float(f["SF"] if f["SF"] is not None else 1.0)  # type: ignore[arg-type]
        motion.append(
            {
                "node": nid_name[n],
                "quantity": ("velocity", "acceleration", "displacement")[vad],
                "direction": "xy"[dof - 1],
                "curve": r.curve(f["LCID"], "time", "LCID"),
                "scale": scale,
            }
        )
    model["prescribed_motion"] = motion


def read_walls(
    r: DeckReader,
    model: dict[str, Any],
    by: dict[str, list[Block]],
    nid_name: dict[int, str],
    dim: int,
    meta: dict[str, Any],
) -> None:
    sets: dict[int, list[int]] = {}
    for b in by.get("SET_NODE_LIST", []):
        h = r.fields(b, b.cards[0], "SET_NODE_LIST") if b.cards else None
        if h is not None:
            ids = [
                v for c in b.cards[1:] if (f := r.fields(b, c, "SET_NODE_LIST_IDS")) for v in f.values() if v
            ]
            sets[int(h["SID"] or 0)] = [int(v) for v in ids]  # type: ignore[call-overload]
    known = {w[0]: w[1] for w in meta.get("walls", [])}
    walls: list[dict[str, Any]] = []
    for b in by.get("RIGIDWALL_PLANAR", []) + by.get("RIGIDWALL_PLANAR_ID", []):
        cards = b.cards
        wid = f"wall-{len(walls) + 1}"
        if b.keyword.endswith("_ID") and cards:
            h = r.fields(b, cards[0], "RIGIDWALL_ID")
            wid = str(h["TITLE"]).strip() if h and h["TITLE"] else f"wall-{h['ID'] if h else len(walls) + 1}"
            cards = cards[1:]
        if len(cards) != 2:
            r.fail(b, f"expected two cards (NSID ... RWKSF, then XT ... WVEL), found {len(cards)}")
            continue
        f1, f2 = r.fields(b, cards[0], "RIGIDWALL_PLANAR"), r.fields(b, cards[1], "RIGIDWALL_PLANAR_2")
        if f1 is None or f2 is None:
            continue
        odd = [k for k in ("NSIDEX", "BOXID", "OFFSET", "RWKSF") if f1[k]] + [
            k for k in ("FRIC", "WVEL") if f2[k]
        ]
        odd += [k for k in ("BIRTH", "DEATH") if f1[k] and abs(float(f1[k])) < NEVER_TIME]  # type: ignore[arg-type]
        tail = [float(f2[k] or 0.0) for k in ("XT", "YT", "ZT")]  # type: ignore[arg-type]
        normal = [float(f2[k] or 0.0) - t for k, t in zip(("XH", "YH", "ZH"), tail, strict=True)]  # type: ignore[arg-type]
        if odd or tail[2] != 0.0 or normal[2] != 0.0 or (dim == 1 and (tail[1] or normal[1])):
            r.fail(
                b,
                "crashstudy walls are stonewalls in the model's plane: NSIDEX, BOXID, OFFSET, RWKSF, FRIC, "
                "WVEL, BIRTH and DEATH blank or 0, z components 0"
                + (f" (found {', '.join(odd)})" if odd else ""),
                cards[0],
            )
            continue
        exact = known.get(wid)
        if (
            exact is not None
            and len(exact) == dim
            and all(abs(a - b2) <= 1e-9 * max(1.0, abs(b2)) for a, b2 in zip(normal, exact, strict=False))
        ):
            normal = list(exact)
        wall: dict[str, Any] = {"id": wid, "point": tail[:dim], "normal": normal[:dim]}
        nsid = int(f1["NSID"] or 0)  # type: ignore[call-overload]
        if nsid:
            if nsid not in sets or any(n not in nid_name for n in sets[nsid]):
                r.fail(b, f"NSID {nsid}: no *SET_NODE_LIST of deck nodes with this id", cards[0], "NSID")
                continue
            wall["nodes"] = [nid_name[n] for n in sets[nsid]]
        walls.append(wall)
    model["rigid_walls"] = walls


def read_controls(
    r: DeckReader,
    model: dict[str, Any],
    by: dict[str, list[Block]],
    rows: Rows,
    meta: dict[str, Any],
    path: str,
) -> None:
    ends = [f["ENDTIM"] for _, _, f in rows["CONTROL_TERMINATION"] if f["ENDTIM"]]
    if not ends:
        r.problems.append(
            Problem(path, None, "*CONTROL_TERMINATION", "no ENDTIM: the deck must give the end time")
        )
    else:
        model["end_time"] = float(ends[-1])  # type: ignore[arg-type]
    if "time_step" in meta:
        model["time_step"] = meta["time_step"]
    else:
        ts = [f for _, _, f in rows["CONTROL_TIMESTEP"] if f["TSSFAC"]]
        if ts and 0.0 < float(ts[-1]["TSSFAC"]) <= 1.0:  # type: ignore[arg-type]
            model["time_step"] = {"safety_factor": float(ts[-1]["TSSFAC"])}  # type: ignore[arg-type]
    if "output" in meta:
        model["output"] = meta["output"]
    else:
        dts = [
            f["DT"]
            for b in by.get("DATABASE_NODOUT", [])
            if b.cards and (f := r.fields(b, b.cards[0], "DATABASE"))
        ]
        if dts and dts[0]:
            model["output"] = {"interval": float(dts[0])}  # type: ignore[arg-type]
    for key in ("termination", "metrics", "accuracy_check"):
        if meta.get(key) not in (None, [], False):
            model[key] = meta[key]
