"""Models made of sub-systems side by side (:func:`disjoint`), and the output of one of them read back as if
it had run alone (:func:`part_of`): one compiled kernel shape serves many small checks."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from crashstudy.kernel.output import ALL_SHAPES, KernelOutput

_CURVE_KEYS = ("loading", "unloading", "curve")


def disjoint(parts: dict[str, dict[str, Any]], base: dict[str, Any] | None = None) -> dict[str, Any]:
    """One model of the sub-systems ``parts`` (prefix -> model without gravity, or with the base's), side by side and
    unconnected: every node, spring, wall and used curve ``id`` becomes ``<prefix>-<id>`` (a part's walls
    hold its own nodes, its loads and prescribed motion act on them); end time, time step and output are
    the first part's. With ``base``, the parts are added beside that model (kept as it is: its ids, walls,
    loads, gravity, prescribed motion, end time, step and output)."""
    first = next(iter(parts.values()))
    model: dict[str, Any] = copy.deepcopy(base) if base else {"name": "-".join(parts)}
    for key in ("curves", "nodes", "springs", "initial_velocity"):
        model.setdefault(key, {})
    for p, part in parts.items():
        assert part.get("gravity", model.get("gravity")) == model.get("gravity"), p  # the base's, if any

        def curve(cid: str, p: str = p, part: dict[str, Any] = part) -> str:
            model["curves"][f"{p}-{cid}"] = part["curves"][cid]
            return f"{p}-{cid}"

        for sid, sp in part["springs"].items() if "springs" in part else ():
            sp = copy.deepcopy(sp)
            sp["nodes"] = [f"{p}-{n}" for n in sp["nodes"]]
            mat = sp["material"]
            for key in _CURVE_KEYS:
                if key in mat:
                    mat[key] = curve(mat[key])
            for rc in mat.get("curves", []):
                rc["curve"] = curve(rc["curve"])
            model["springs"][f"{p}-{sid}"] = sp
        model["nodes"].update({f"{p}-{n}": copy.deepcopy(v) for n, v in part["nodes"].items()})
        model["initial_velocity"].update({f"{p}-{n}": v for n, v in part.get("initial_velocity", {}).items()})
        for wall in part.get("rigid_walls", []):
            wall = copy.deepcopy(wall)
            wall["id"], wall["nodes"] = f"{p}-{wall['id']}", [f"{p}-{n}" for n in wall["nodes"]]
            model.setdefault("rigid_walls", []).append(wall)
        for key in ("loads", "prescribed_motion"):
            for item in part.get(key, []):
                item = dict(item, node=f"{p}-{item['node']}")
                if "curve" in item:
                    item["curve"] = curve(item["curve"])
                model.setdefault(key, []).append(item)
    if base is None:
        model.update({k: copy.deepcopy(first[k]) for k in ("end_time", "time_step", "output") if k in first})
    return model


def part_of(out: KernelOutput, plan: Any, prefix: str) -> KernelOutput:
    """The output of sub-system ``prefix`` of a :func:`disjoint` model, as if it had run alone: its nodes,
    springs and walls in their order (per-variant numbers, e.g. ``status``, are the whole model's)."""
    topo = plan.topology

    def own(ids: Any) -> list[int]:
        return [k for k, i in enumerate(ids) if i.startswith(prefix + "-")]

    take = {"node": own(topo.node_ids), "spring": own(topo.spring_ids), "wall": own(topo.wall_ids)}
    per = {"peak_acceleration": "node", "peak_wall_force": "wall", "wall_impulse": "wall"}
    per |= {f: "spring" for f in ("peak_force", "max_crush", "absorbed_energy", "max_elongation")}
    per |= {"spring_fail_time": "spring"}
    part = copy.copy(out)
    for name, dim in per.items():
        setattr(part, name, getattr(out, name)[take[dim]])
    part.histories = {}
    for name, h in out.histories.items():
        for axis, dim in enumerate(ALL_SHAPES[name], start=1):
            h = np.take(h, take[dim], axis=axis) if dim in take else h
        part.histories[name] = h
    return part
