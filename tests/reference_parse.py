"""The scipy reference solver's reading of a model dict (docs/format.md) into its :class:`_Model`, refusing
the materials and keys it does not support. Part of the independent scipy reference solver
(reference_scipy.py, which describes its scope, physics and numerics); like it, it does not import
``crashstudy``."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from reference_model import _AXES, _Curve, _Load, _Model, _parse_curve

SUPPORTED_MATERIALS = ("linear_elastic", "nonlinear_elastic", "damper")
UNSUPPORTED_MATERIALS = ("general_nonlinear", "crush")
_UNSUPPORTED_KEYS = ("prescribed_motion", "rigid_walls")


def _parse_fixed(value: Any, dim: int, where: str) -> np.ndarray:
    mask = np.zeros(dim, dtype=bool)
    if value is None or value is False:
        return mask
    if value is True:
        return ~mask
    if isinstance(value, str):
        value = [value]
    if isinstance(value, Sequence):
        items = list(value)
        if items and all(isinstance(it, (bool, np.bool_)) for it in items):
            if len(items) != dim:
                raise ValueError(f"{where}.fixed: {len(items)} flags for a {dim}-D model")
            return np.array(items, dtype=bool)
        for it in items:
            name = str(it).strip().lower()
            if name not in _AXES[:dim]:
                raise ValueError(f"{where}.fixed: unknown axis {it!r} (expected {list(_AXES[:dim])})")
            mask[_AXES.index(name)] = True
        return mask
    raise ValueError(f"{where}.fixed: expected true/false or a list of axes, got {value!r}")


def _vector(value: Any, dim: int, where: str) -> np.ndarray:
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    if arr.shape != (dim,):
        raise ValueError(f"{where}: expected {dim} component(s), got {value!r}")
    return arr


def _compile(model: Mapping[str, Any]) -> _Model:
    for key in _UNSUPPORTED_KEYS:
        if model.get(key):
            raise NotImplementedError(f"reference_scipy does not support {key!r}")

    curves = {str(cid): _parse_curve(str(cid), raw) for cid, raw in (model.get("curves") or {}).items()}

    nodes_raw = model.get("nodes") or {}
    if not nodes_raw:
        raise ValueError("model has no nodes")
    node_ids = tuple(str(k) for k in nodes_raw)
    positions = [np.atleast_1d(np.asarray(nodes_raw[k]["position"], dtype=float)) for k in nodes_raw]
    dims = {p.size for p in positions}
    if len(dims) != 1 or dims.pop() not in (1, 2):
        raise ValueError("every node position must have the same number (1 or 2) of coordinates")
    dim = positions[0].size
    x0 = np.array(positions, dtype=float).reshape(len(node_ids), dim)
    index = {nid: k for k, nid in enumerate(node_ids)}

    mass = np.zeros(len(node_ids))
    free = np.ones((len(node_ids), dim), dtype=bool)
    for k, (nid, raw) in enumerate(nodes_raw.items()):
        free[k] = ~_parse_fixed(raw.get("fixed"), dim, f"nodes.{nid}")
        m = raw.get("mass")
        if free[k].any():
            if m is None or not float(m) > 0.0:
                raise ValueError(f"nodes.{nid}: a node that is not fixed in every direction needs mass > 0")
        mass[k] = float(m) if m is not None else 0.0
    inv_mass = np.zeros_like(x0)
    with np.errstate(divide="ignore"):
        inv_mass[free] = np.broadcast_to((1.0 / np.where(mass > 0, mass, 1.0))[:, None], x0.shape)[free]

    v0 = np.zeros_like(x0)
    for nid, vel in (model.get("initial_velocity") or {}).items():
        if str(nid) not in index:
            raise ValueError(f"initial_velocity: unknown node {nid!r}")
        k = index[str(nid)]
        v0[k] = _vector(vel, dim, f"initial_velocity.{nid}")
        if np.any(v0[k][~free[k]] != 0.0):
            raise ValueError(f"initial_velocity.{nid}: non-zero velocity along a fixed direction")

    gravity = np.zeros(dim)
    if model.get("gravity") is not None:
        gravity = _vector(model["gravity"], dim, "gravity")

    springs_raw = model.get("springs") or {}
    spring_ids = tuple(str(k) for k in springs_raw)
    ni = np.zeros(len(spring_ids), dtype=int)
    nj = np.zeros(len(spring_ids), dtype=int)
    materials: list[str] = []
    lin_idx: list[int] = []
    lin_k: list[float] = []
    damp_idx: list[int] = []
    damp_c: list[float] = []
    curve_springs: list[tuple[int, _Curve]] = []
    for s, (sid, raw) in enumerate(springs_raw.items()):
        pair = list(raw["nodes"])
        if len(pair) != 2 or pair[0] == pair[1] or any(str(p) not in index for p in pair):
            raise ValueError(f"springs.{sid}.nodes: expected two different known nodes, got {pair!r}")
        ni[s], nj[s] = index[str(pair[0])], index[str(pair[1])]
        mat = raw["material"]
        kind = str(mat["type"])
        materials.append(kind)
        if kind == "linear_elastic":
            lin_idx.append(s)
            lin_k.append(float(mat["stiffness"]))
        elif kind == "nonlinear_elastic":
            cid = str(mat["curve"])
            if cid not in curves:
                raise ValueError(f"springs.{sid}.material.curve: unknown curve {cid!r}")
            curve_springs.append((s, curves[cid]))
        elif kind == "damper":
            damp_idx.append(s)
            damp_c.append(float(mat["damping"]))
        elif kind in UNSUPPORTED_MATERIALS:
            raise NotImplementedError(f"springs.{sid}: material {kind!r} is not supported by the reference")
        else:
            raise ValueError(f"springs.{sid}.material.type: unknown material {kind!r}")
    d0 = x0[nj] - x0[ni]
    l0 = np.sqrt(np.sum(d0 * d0, axis=-1))
    if np.any(l0 == 0.0):
        raise ValueError("every spring needs a non-zero initial length")
    sign = np.sign(d0[:, 0]) if dim == 1 else np.ones(len(spring_ids))
    incidence = np.zeros((len(node_ids), len(spring_ids)))
    incidence[ni, np.arange(len(spring_ids))] += 1.0
    incidence[nj, np.arange(len(spring_ids))] -= 1.0

    loads: list[_Load] = []
    for k, raw in enumerate(model.get("loads") or []):
        nid = str(raw["node"])
        if nid not in index:
            raise ValueError(f"loads[{k}].node: unknown node {nid!r}")
        curve = None
        if raw.get("curve") is not None:
            cid = str(raw["curve"])
            if cid not in curves:
                raise ValueError(f"loads[{k}].curve: unknown curve {cid!r}")
            curve = curves[cid]
        loads.append(
            _Load(node=index[nid], force=_vector(raw["force"], dim, f"loads[{k}].force"), curve=curve)
        )

    end_time = float(model["end_time"])
    if not end_time > 0.0:
        raise ValueError("end_time must be > 0")

    return _Model(
        node_ids=node_ids,
        spring_ids=spring_ids,
        dim=dim,
        x0=x0,
        mass=mass,
        free=free,
        inv_mass=inv_mass,
        v0=v0,
        gravity=gravity,
        ni=ni,
        nj=nj,
        d0=d0,
        l0=l0,
        sign=sign,
        incidence=incidence,
        materials=tuple(materials),
        lin_idx=np.array(lin_idx, dtype=int),
        lin_k=np.array(lin_k, dtype=float),
        damp_idx=np.array(damp_idx, dtype=int),
        damp_c=np.array(damp_c, dtype=float),
        curve_springs=tuple(curve_springs),
        loads=tuple(loads),
        end_time=end_time,
    )
