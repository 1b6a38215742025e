"""The ISO-MME channels of one variant of a result folder (``crashstudy export DIR --isomme OUT``,
docs/isomme.md): which histories become which channel code, in SI units.

A code is the item's 12-character prefix (the model's ``iso_mme:`` map, else ``10NODEnnnn00`` for the n-th
node and ``10SPRGnnnn00`` for the n-th spring, in model order), then the physical dimension (AC, VE, DS, FO),
the direction (X, Y; R resultant; 0 for a spring's axial value) and the filter class (0 raw; A/B/C/D for
CFC 1000/600/180/60). ``Name of the channel`` is ``<id> <history> [<axis>]``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from crashstudy.exchange.isomme import OutChannel
from crashstudy.units import si_per_unit

#: SAE J211 channel frequency class -> the code's last character
FILTER_LETTER = {1000: "A", 600: "B", 180: "C", 60: "D"}
#: history -> (physical dimension of the code, unit kind, SI unit as ISO/TS 13499 writes it)
NODE_HISTORIES = {
    "acceleration": ("AC", "acceleration", "m/(s*s)"),
    "velocity": ("VE", "velocity", "m/s"),
    "displacement": ("DS", "length", "m"),
}
SPRING_HISTORIES = {"spring_force": ("FO", "force", "N"), "spring_elongation": ("DS", "length", "m")}
G = 9.80665  # m/s^2: filtered_acceleration is stored in g


def default_prefix(kind: str, position: int) -> str:
    """The documented default 12-character prefix of the ``position``-th (1-based) node or spring."""
    return f"10{'NODE' if kind == 'node' else 'SPRG'}{position:04d}00"


def prefixes(model: dict[str, Any], nodes: list[str], springs: list[str]) -> dict[str, str]:
    """Item id -> its 12-character prefix: the model's ``iso_mme:`` entry or the default."""
    given = dict(model.get("iso_mme") or {})
    out = {n: given.get(n, default_prefix("node", k)) for k, n in enumerate(nodes, 1)}
    out.update({s: given.get(s, default_prefix("spring", k)) for k, s in enumerate(springs, 1)})
    return out


def metric_filters(model: dict[str, Any]) -> dict[str, int]:
    """Metric node -> the CFC of its filtered acceleration (the first metrics entry of the node)."""
    out: dict[str, int] = {}
    for m in model.get("metrics") or []:
        out.setdefault(str(m["node"]), int(m.get("cfc", 180)))
    return out


def variant_channels(ds: Any, variant: int, model: dict[str, Any], free_nodes: list[str]) -> list[OutChannel]:
    """The channels of ``variant`` (an index along the dataset's ``variant``): every kept history of every
    free node (per axis), the filtered acceleration of metric nodes, and every spring's force and
    elongation, converted from the folder's unit system into SI."""
    system = str(ds.attrs.get("units", "SI"))
    times = np.asarray(ds["time"].values, dtype=float) * si_per_unit(system, "time")
    t0, dt = float(times[0]), float(np.mean(np.diff(times))) if len(times) > 1 else 0.0
    nodes = [str(n) for n in ds["node"].values]
    springs = [str(s) for s in ds["spring"].values] if "spring" in ds.dims else []
    pre = prefixes(model, nodes, springs)
    axes = [str(a) for a in ds["axis"].values]
    out: list[OutChannel] = []
    for name, (dim, kind, unit) in NODE_HISTORIES.items():
        if name not in ds:
            continue
        h = np.asarray(ds[name].isel(variant=variant).values, dtype=float) * si_per_unit(
            system, kind
        )  # (T, N, A)
        for i, node in enumerate(nodes):
            if node not in free_nodes:
                continue
            for a, axis in enumerate(axes):
                out.append(
                    OutChannel(
                        f"{pre[node]}{dim}{axis.upper()}0", f"{node} {name} {axis}", unit, t0, dt, h[:, i, a]
                    )
                )
    if "filtered_acceleration" in ds:
        h = (
            np.asarray(ds["filtered_acceleration"].isel(variant=variant).values, dtype=float) * G
        )  # (T, N) in g
        for node, cfc in metric_filters(model).items():
            if node in nodes:
                out.append(
                    OutChannel(
                        f"{pre[node]}ACR{FILTER_LETTER[cfc]}",
                        f"{node} filtered_acceleration CFC {cfc}",
                        "m/(s*s)",
                        t0,
                        dt,
                        h[:, nodes.index(node)],
                        (("Channel frequency class", str(cfc)),),
                    )
                )
    for name, (dim, kind, unit) in SPRING_HISTORIES.items():
        if name not in ds:
            continue
        h = np.asarray(ds[name].isel(variant=variant).values, dtype=float) * si_per_unit(
            system, kind
        )  # (T, S)
        for j, spring in enumerate(springs):
            out.append(OutChannel(f"{pre[spring]}{dim}00", f"{spring} {name}", unit, t0, dt, h[:, j]))
    return out


def parse_selection(text: str, count: int) -> list[int]:
    """Variants of ``--variants``: comma-separated numbers and inclusive ranges (``0,5,10-20``), each within
    0 .. count - 1; raises ValueError saying what was expected."""
    chosen: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        lo, sep, hi = part.partition("-")
        try:
            a, b = (int(lo), int(hi)) if sep else (int(part), int(part))
        except ValueError:
            raise ValueError(f"{part!r}: expected a variant number or a range A-B (e.g. 0,5,10-20)") from None
        if not 0 <= a <= b < count:
            raise ValueError(
                f"{part!r}: expected variants within 0 .. {count - 1} (and A <= B in a range A-B)"
            )
        chosen.update(range(a, b + 1))
    return sorted(chosen)
