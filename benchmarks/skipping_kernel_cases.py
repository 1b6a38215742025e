"""Comparisons 1-5 of the skipping benchmark, on the kernel: histories, 1-D vs 2-D geometry, a wall or
load that does nothing, material state, early termination.

Part of benchmarks/skipping.py (what skipping costs and saves, issue 4, item 3), which describes the
comparisons and how they are timed."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

from skipping_measure import (
    PLOTTED,
    Row,
    finish_kernel_case,
    fmt_case,
    frontal,
    gain,
    hist_bytes,
    kernel_case,
    measure,
    rel_diff,
)

# ---------------------------------------------------------------------------------------------- comparisons


def cmp_histories(V: int, repeats: int, log: list[str]) -> list[Row]:
    cases = [
        kernel_case("histories: all", frontal("all"), V),
        kernel_case("histories: [spring_force]", frontal(["spring_force"]), V),
        kernel_case("histories: none", frontal("none"), V),
    ]
    before, after = measure(cases, repeats)
    for c in cases:
        finish_kernel_case(c)
    mem = {c.name: hist_bytes(c.result, c.plan.topology.histories, c.plan.n_out, V) for c in cases}  # type: ignore[attr-defined]
    PLOTTED.append(("1. histories", cases))
    log.append(f"1. histories, {V} variants, load {before} -> {after}")
    for c in cases:
        log.append(f"   {fmt_case(c)}; history arrays {mem[c.name] / 2**20:.1f} MiB {c.note}")
    base = cases[0]
    rows = []
    for c in cases[1:]:
        d = rel_diff(c.result, base.result, base.plan, 0.0)  # type: ignore[attr-defined]
        rows.append(
            Row(
                f"histories ({V} variants): {c.name.split(': ')[1]} instead of all",
                f"{fmt_case(base)}; arrays {mem[base.name] / 2**20:.0f} MiB",
                f"{fmt_case(c)}; arrays {mem[c.name] / 2**20:.1f} MiB",
                gain(base, c),
                f"peaks vs `all`: {d.text(V)}",
            )
        )
    return rows


def stretched(d: dict[str, Any], factor: float) -> dict[str, Any]:
    """The model drawn ``factor`` times longer (in 1-D the drawing only gives each spring's direction)."""
    d = copy.deepcopy(d)
    for node in d["nodes"].values():
        node["position"] = [p * factor for p in node["position"]]
    return d


def to_2d(d: dict[str, Any], y_fixed: bool) -> dict[str, Any]:
    """The same 1-D model drawn along the x axis of a 2-D model: positions [x, 0], velocities [v, 0]."""
    d = copy.deepcopy(d)
    for node in d["nodes"].values():
        node["position"] = [node["position"][0], 0.0]
        if node.get("fixed") is not True:
            node["fixed"] = ["y"] if y_fixed else False
    d["initial_velocity"] = {k: [v[0], 0.0] for k, v in d["initial_velocity"].items()}
    return d


def cmp_geometry(V: int, repeats: int, log: list[str], factor: float = 2.0) -> list[Row]:
    """1-D vs 2-D on the frontal model drawn ``factor`` x longer.

    As drawn in the file, the crash box (0.15 m) is crushed past zero length (the bumper passes the
    barrier; 1-D elongation down to about -0.150 m): in 1-D that is still the curve's bottoming, in
    2-D the spring turns inside out. Drawn twice as long every spring keeps over a quarter of its
    length in every sampled variant (the share left is reported), so the two models are the same physics; the 1-D results of the
    stretched drawing are checked against the file's drawing.
    """
    orig = frontal("none")
    base = stretched(orig, factor)
    cases = [
        kernel_case("2-D, y fixed", to_2d(base, True), V),
        kernel_case("2-D, y free", to_2d(base, False), V),
        kernel_case("1-D", base, V),
    ]
    same_dt = all(np.array_equal(c.batch.dt, cases[2].batch.dt) for c in cases)  # type: ignore[attr-defined]
    before, after = measure(cases, repeats)
    for c in cases:
        finish_kernel_case(c)
    one = cases[2]
    drawn = kernel_case("1-D as drawn in the file", orig, V)
    d_drawn = rel_diff(drawn.run(), one.result, one.plan, 1e-9)  # type: ignore[attr-defined]
    left = float(np.min(1.0 - cases[0].result.max_crush / cases[0].batch.length0))  # type: ignore[attr-defined]
    PLOTTED.append(("2. geometry", cases))
    log.append(
        f"2. 1-D vs 2-D along x, model drawn {factor:g}x longer, {V} variants (same dt in every case: "
        f"{same_dt}), load {before} -> {after}"
    )
    log.append(
        f"   1-D drawn {factor:g}x vs as in the file: peaks {d_drawn.text(V)}; shortest spring "
        f"in 2-D keeps {left:.0%} of its length"
    )
    rows = []
    for c in cases[:2]:
        d = rel_diff(c.result, one.result, one.plan, 1e-9)  # type: ignore[attr-defined]
        log.append(f"   {fmt_case(c)} {c.note}; peaks vs 1-D {d.text(V)}")
        rows.append(
            Row(
                f"geometry: 1-D instead of {c.name} ({V} variants)",
                fmt_case(c),
                fmt_case(one),
                gain(c, one),
                f"peaks (force, accel., crush) vs 1-D: {d.text(V)}",
            )
        )
    log.append(f"   {fmt_case(one)} {one.note}")
    return rows


def cmp_wall_load(V: int, repeats: int, log: list[str]) -> list[Row]:
    base = frontal("none")
    wall = copy.deepcopy(base)
    wall["rigid_walls"] = [{"id": "far", "point": [-100.0], "normal": [1.0]}]  # 100 m behind the barrier
    load = copy.deepcopy(base)
    load["loads"] = [{"node": "survival_room", "force": [0.0]}]
    cases = [
        kernel_case("wall never reached", wall, V),
        kernel_case("zero load", load, V),
        kernel_case("neither (fused 1-D update)", base, V),
    ]
    before, after = measure(cases, repeats)
    for c in cases:
        finish_kernel_case(c)
    ref = cases[2]
    PLOTTED.append(("3. wall / load", cases))
    log.append(f"3. wall / load vs neither, {V} variants, load {before} -> {after}")
    rows = []
    for c in cases[:2]:
        d = rel_diff(c.result, ref.result, ref.plan, 1e-12)  # type: ignore[attr-defined]
        extra = ""
        if c.name.startswith("wall"):
            extra = f"; peak wall force {float(np.max(c.result.peak_wall_force)):.1g}"
        log.append(f"   {fmt_case(c)} {c.note}; peaks vs neither {d.text(V)}{extra}")
        rows.append(
            Row(
                f"no {c.name.split(' ')[0]} loop, fused 1-D update ({V} variants)",
                fmt_case(c),
                fmt_case(ref),
                gain(c, ref),
                f"peaks vs neither: {d.text(V)}{extra}",
            )
        )
    log.append(f"   {fmt_case(ref)} {ref.note}")
    return rows


def with_material(d: dict[str, Any], kind: str) -> dict[str, Any]:
    """Every curve-driven spring of the frontal model as ``kind`` on its own loading curve.

    crush: unloading_stiffness = the model's (crush springs) or the unloading curve's slope;
    general_nonlinear: unloading = the model's curve or a straight line of the crush unloading
    stiffness, yields as in the model (none for the former crush springs). gearbox-flange stays linear.
    """
    d = copy.deepcopy(d)
    for sid, s in d["springs"].items():
        m = s["material"]
        if m["type"] not in ("crush", "general_nonlinear"):
            continue
        loading = m["loading"]
        if m["type"] == "crush":
            k = m["unloading_stiffness"]
            unl = f"{sid}-unloading"
            d["curves"][unl] = {"x": [-1.0, 0.0, 1.0], "y": [-k, 0.0, k]}
            yields = {}
        else:
            unl = m["unloading"]
            c = d["curves"][unl]
            k = (c["y"][-1] - c["y"][0]) / (c["x"][-1] - c["x"][0])
            yields = {key: m[key] for key in ("tension_yield", "compression_yield") if key in m}
        if kind == "nonlinear_elastic":
            s["material"] = {"type": kind, "curve": loading}
        elif kind == "crush":
            s["material"] = {"type": kind, "loading": loading, "unloading_stiffness": float(k)}
        else:
            s["material"] = {"type": kind, "loading": loading, "unloading": unl, **yields}
    return d


def cmp_material(V: int, repeats: int, log: list[str]) -> list[Row]:
    base = frontal("none")
    cases = [
        kernel_case(f"all {k}", with_material(base, k), V)
        for k in ("general_nonlinear", "crush", "nonlinear_elastic")
    ]
    before, after = measure(cases, repeats)
    for c in cases:
        finish_kernel_case(c)
    PLOTTED.append(("4. material state", cases))
    log.append(f"4. material state, {V} variants, load {before} -> {after}")
    for c in cases:
        dts = np.unique(c.batch.dt)  # type: ignore[attr-defined]
        log.append(f"   {fmt_case(c)} {c.note}; dt {dts.min():.3g}..{dts.max():.3g} s")
    ne = cases[2]
    return [
        Row(
            f"no material state: 7 curve springs nonlinear_elastic instead of {c.name.split(' ')[1]} "
            f"({V} variants)",
            fmt_case(c),
            fmt_case(ne),
            gain(c, ne),
            "different physics: cost only",
        )
        for c in cases[:2]
    ]


def cmp_termination(V: int, repeats: int, log: list[str]) -> list[Row]:
    """end_time 0.3 s with and without ``termination``: 1% (the asked-for setting) and 5% of the KE."""
    long_run = frontal("none")
    long_run["end_time"] = 0.3
    long_run["output"]["interval"] = 3.0e-4
    cases = [kernel_case("end_time 0.3 s, no termination", long_run, V)]
    for frac in (0.01, 0.05):
        term = copy.deepcopy(long_run)
        term["termination"] = {"kinetic_energy_fraction": frac}
        cases.append(kernel_case(f"termination KE {frac:.0%}", term, V))
    before, after = measure(cases, repeats)
    for c in cases:
        finish_kernel_case(c)
    full = cases[0]
    PLOTTED.append(("5. termination", cases))
    log.append(f"5. early termination, end_time 0.3 s, {V} variants, load {before} -> {after}")
    log.append(f"   {fmt_case(full)} {full.note}")
    rows = []
    for cut in cases[1:]:
        d = rel_diff(cut.result, full.result, full.plan, 1e-12)  # type: ignore[attr-defined]
        te = cut.result.t_end
        stopped = float(np.mean(te < 0.3 - 1e-9))
        log.append(
            f"   {fmt_case(cut)} {cut.note}; {stopped:.0%} of the variants stopped early, t_end "
            f"min/median/max {te.min():.4f}/{np.median(te):.4f}/{te.max():.4f} s; peaks {d.text(V)}"
        )
        steps = (
            f"variant-steps {full.elem_steps / 8:.3g} -> {cut.elem_steps / 8:.3g} ({full.elem_steps / cut.elem_steps:.2f}x; "
            f"{stopped:.0%} stopped early, t_end median {np.median(te):.3f} s)"
        )
        rows.append(
            Row(
                f"early termination, {cut.name} ({V} variants, end_time 0.3 s)",
                fmt_case(full),
                fmt_case(cut),
                f"wall {full.wall_med / cut.wall_med:.2f}x, CPU {full.cpu_med / cut.cpu_med:.2f}x; {steps}",
                f"peaks vs no termination: {d.text(V)}",
            )
        )
    return rows
