"""Every path of the ``general_nonlinear`` spring material law (docs/format.md, rules 1-4), checked
against an independent oracle; and the oracle's own curve helpers.

Each test drives one 1-D spring through a prescribed elongation history and checks its force history
against an independent oracle of docs/format.md (to 1e-9 of the peak force), hand-computed values at the
turning points, and the compiled against the reference kernel (to 1e-12 of the peak): material_oracle.py
describes the oracle and the driving."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from material_oracle import PL, Driven, GeneralNonlinearOracle, driven_spring


def test_oracle_curve_helpers() -> None:
    """The oracle's own curve: interpolation, extrapolation and the crossing finder."""
    c = PL([-1.0, 0.0, 2.0], [-10.0, 0.0, 4.0])
    assert c(-3.0) == -30.0 and c(-0.5) == -5.0 and c(1.0) == 2.0 and c(4.0) == 8.0
    assert c.solve(-30.0) == -3.0 and c.solve(8.0) == 4.0
    dip = PL([0.0, 0.23, 0.6, 0.9, 1.25, 1.5], [0.0, 20.0, 23.0, 18.0, 20.0, 35.0])  # Table 3
    with pytest.raises(AssertionError, match="3 crossings"):
        dip.solve(21.0, 0.0)
    assert dip.solve(30.0, 0.0) == pytest.approx(1.5 - 5.0 / 60.0, abs=1e-15)


# the curves of the general_nonlinear paths
TABLE3_LOADING = {"x": [0.0, 0.23, 0.6, 0.9, 1.25, 1.5], "y": [0.0, 20.0, 23.0, 18.0, 20.0, 35.0]}  # mm, kN
TABLE2_UNLOADING = {"x": [0.0, 0.1, 7.0], "y": [0.0, 1.0, 70.0]}  # mm, kN (as written: tension only)
TABLE4_LOADING = {"x": [-0.3, -0.27, -0.225, -0.01, 0.0], "y": [-1.0e6, -5.0e5, -1.5e5, -1.5e5, 0.0]}  # m, N
TABLE4_UNLOADING = {"x": [-0.006, 0.0, 0.006], "y": [-1.7e5, 0.0, 1.7e5]}  # m, N


def gn(
    loading: dict[str, list[float]], unloading: dict[str, list[float]], ty: float | None, yc: float | None
) -> tuple[dict[str, Any], GeneralNonlinearOracle]:
    """A general_nonlinear material block (curves 'L', 'U') and its oracle."""
    mat: dict[str, Any] = {"type": "general_nonlinear", "loading": "L", "unloading": "U"}
    if ty is not None:
        mat["tension_yield"] = ty
    if yc is not None:
        mat["compression_yield"] = yc
    return mat, GeneralNonlinearOracle(PL(**loading), PL(**unloading), ty, yc)


# --------------------------------------------------------------------------------------------------
# general_nonlinear
# --------------------------------------------------------------------------------------------------


def test_elastic_load_and_unload_inside_the_yield_band_follow_the_loading_curve_both_ways() -> None:
    """Paper points 1-2 (Tables 2-3, mm/kN, tension_yield 20): below yield, unloading stays on L."""
    mat, oracle = gn(TABLE3_LOADING, TABLE2_UNLOADING, 20.0, None)
    # u [mm] vs t [ms]: 0 -> 0.2 (point 1) -> 0.05 (point 2) -> 0.2 -> -0.1 (compression, elastic) -> 0
    path = [(0.0, 0.0), (2.0, 0.2), (3.5, 0.05), (5.0, 0.2), (8.0, -0.1), (9.0, 0.0)]
    run = Driven(driven_spring(mat, {"L": TABLE3_LOADING, "U": TABLE2_UNLOADING}, path, 0.05, "mm-ms-kg-kN"))
    expected = run.check_oracle(oracle)
    k = 20.0 / 0.23  # kN/mm, first segment of L (also its extrapolation into compression)
    assert np.max(np.abs(expected - k * run.e)) <= 1e-12 * run.peak  # F = L(e) throughout
    assert run.at(2.0) == run.approx(17.391304347826086)  # point 1
    assert run.at(3.5) == run.approx(4.3478260869565215)  # point 2: on L, not 17.39 + U(-0.15) = 15.89
    assert run.at(5.0) == run.approx(17.391304347826086)
    assert run.at(8.0) == run.approx(-8.695652173913043)
    assert run.at(9.0) == run.approx(0.0)
    assert oracle.active is None  # never yielded


def test_tension_yield_unloads_on_the_shifted_unloading_curve_and_reloads_to_rejoin_loading() -> None:
    """Paper points 3-5 (Tables 2-3, tension_yield 20 kN): the unloading curve is shifted to (e*, F*),
    reloading runs back along it and rejoins L at e*."""
    mat, oracle = gn(TABLE3_LOADING, TABLE2_UNLOADING, 20.0, None)
    path = [(0.0, 0.0), (2.0, 0.2), (3.5, 0.05), (16.0, 1.3), (21.0, 0.8), (27.0, 1.4), (30.0, 1.4)]
    run = Driven(driven_spring(mat, {"L": TABLE3_LOADING, "U": TABLE2_UNLOADING}, path, 0.05, "mm-ms-kg-kN"))
    run.check_oracle(oracle)
    assert run.at(2.0) == run.approx(17.391304347826086)  # point 1
    assert run.at(3.5) == run.approx(4.3478260869565215)  # point 2
    assert run.at(16.0) == run.approx(23.0)  # point 3: L(1.3) = 20 + 60 * 0.05; e* = 1.3, F* = 23
    assert run.at(21.0) == run.approx(18.0)  # point 4: 23 + U(0.8 - 1.3) = 23 - 5 (L(0.8) would be 19.67)
    assert run.at(23.0) == run.approx(20.0)  # reloading on the same line, e = 1.0 (L(1.0) = 18.57)
    assert run.at(26.0) == run.approx(23.0)  # back at e* = 1.3
    assert run.at(27.0) == run.approx(29.0)  # point 5: on L again, 20 + 60 * 0.15
    assert oracle.active == +1 and oracle.extreme[+1] == (pytest.approx(1.4), pytest.approx(29.0))


def test_compression_yield_with_table4_cabin_curves() -> None:
    """Table 4 (m, N), compression_yield -150 kN, no tension yield: elastic on L, yield at -10 mm,
    plateau, stiffening, unloading on the shifted unloading line far into tension (never yields in
    tension), reloading back onto L beyond e*."""
    mat, oracle = gn(TABLE4_LOADING, TABLE4_UNLOADING, None, -150000.0)
    path = [
        (0.0, 0.0),
        (0.005, -0.005),
        (0.008, -0.002),
        (0.156, -0.15),
        (0.256, -0.25),
        (0.266, -0.24),
        (0.276, -0.23),
        (0.306, -0.26),
        (0.31, -0.26),
    ]
    run = Driven(driven_spring(mat, {"L": TABLE4_LOADING, "U": TABLE4_UNLOADING}, path, 2.5e-4, "SI"))
    run.check_oracle(oracle)
    ku = 1.7e5 / 0.006
    f_star = -1.5e5 - 0.025 * 3.5e5 / 0.045  # L(-0.25) = -344444.44 N
    assert run.at(0.005) == run.approx(-75000.0)  # elastic, 1.5e7 N/m
    assert run.at(0.008) == run.approx(-30000.0)  # unloaded along L (not yielded)
    assert run.at(0.156) == run.approx(-150000.0)  # yielded at -0.01 m, on the plateau
    assert run.at(0.256) == run.approx(f_star)
    assert run.at(0.266) == run.approx(f_star + 0.01 * ku)  # -61111.11: unloading line through (e*, F*)
    assert run.at(0.276) == run.approx(f_star + 0.02 * ku)  # +222222.22 N: tension on the line
    assert run.at(0.286) == run.approx(f_star + 0.01 * ku)  # reloading on the same line
    assert run.at(0.296) == run.approx(f_star)  # back at e* = -0.25
    assert run.at(0.306) == run.approx(-500000.0 + 0.01 * 3.5e5 / 0.045)  # L(-0.26) = -422222.22
    assert oracle.active == -1 and not oracle.yielded[+1]


def test_reverse_yield_follows_the_shifted_loading_curve_and_the_tension_threshold_becomes_f_star() -> None:
    """Rule 4 both ways. L: slope 100 to +-1 (+-100 N), then 50; U: slope 1000; yields +100 / -100.

    - load to e = 1.5: yield at 1, e_t* = 1.5, F_t* = 125;
    - unload: 125 + 1000 (e - 1.5) reaches -100 (initial compression yield) at 1.275; L(x) = -100 at
      x = -1, so the shift is 2.275; at e = 0.775, F = L(-1.5) = -125 = F_c*;
    - reload: -125 + 1000 (e - 0.775) reaches F_t* = 125 (not the initial 100) at 1.025; L(x) = 125
      at x = 1.5, shift -0.475; at e = 1.525, F = L(2.0) = 150; at 1.825, L(2.3) = 165 (extrapolated);
    - unload again: 165 + 1000 (e - 1.825) reaches F_c* = -125 at 1.535; shift 1.535 + 1.5 = 3.035;
      at e = 1.2, F = L(-1.835) = -141.75; reload to 1.3 on the line: -41.75.
    """
    L = {"x": [-2.0, -1.0, 0.0, 1.0, 2.0], "y": [-150.0, -100.0, 0.0, 100.0, 150.0]}
    U = {"x": [-1.0, 0.0, 1.0], "y": [-1000.0, 0.0, 1000.0]}
    mat, oracle = gn(L, U, 100.0, -100.0)
    path = [(0.0, 0.0), (1.5, 1.5), (2.225, 0.775), (2.975, 1.525), (3.275, 1.825), (3.9, 1.2), (4.0, 1.3)]
    run = Driven(driven_spring(mat, {"L": L, "U": U}, path, 5.0e-3))
    run.check_oracle(oracle)
    assert run.at(1.5) == run.approx(125.0)
    assert run.at(1.6) == run.approx(25.0)  # e = 1.4, on the unloading line
    assert run.at(2.0) == run.approx(-113.75)  # e = 1.0, compression loading curve shifted by 2.275
    assert run.at(2.225) == run.approx(-125.0)
    assert run.at(2.4) == run.approx(50.0)  # e = 0.95, unloading line from the compression extreme
    assert run.at(2.6) == run.approx(131.25)  # e = 1.15, tension curve shifted by -0.475 (not by 0)
    assert run.at(2.975) == run.approx(150.0)
    assert run.at(3.275) == run.approx(165.0)
    assert run.at(3.9) == run.approx(-141.75)
    assert run.at(4.0) == run.approx(-41.75)
    assert oracle.shift == pytest.approx(3.035, abs=1e-6)


def test_absent_tension_yield_never_yields_in_tension() -> None:
    """No tension_yield: far past 20 kN in tension the spring stays on L both ways; after a compression
    yield, the unloading line runs into tension without ever switching to the loading curve."""
    mat, oracle = gn(TABLE3_LOADING, TABLE2_UNLOADING, None, -5.0)
    path = [(0.0, 0.0), (14.0, 1.4), (25.0, 0.3), (36.5, 1.45), (51.0, 0.0), (52.0, -0.1), (68.0, 1.5)]
    run = Driven(driven_spring(mat, {"L": TABLE3_LOADING, "U": TABLE2_UNLOADING}, path, 0.1, "mm-ms-kg-kN"))
    expected = run.check_oracle(oracle)
    first = run.t <= 51.0 + 1e-9
    loading = PL(**TABLE3_LOADING)
    on_l = np.array([loading(e) for e in run.e[first]])
    assert np.max(np.abs(expected[first] - on_l)) <= 1e-12 * run.peak  # pure elastic on L in tension
    assert run.at(14.0) == run.approx(29.0)
    assert run.at(25.0) == run.approx(20.0 + 3.0 / 0.37 * 0.07)  # L(0.3), unloading on L
    assert run.at(36.5) == run.approx(32.0)
    assert run.at(51.0) == run.approx(0.0)
    f_c = -0.1 * 20.0 / 0.23  # L(-0.1), extrapolated; compression yielded at -5 kN
    assert run.at(52.0) == run.approx(f_c)
    assert run.at(68.0) == run.approx(f_c + 10.0 * 1.6)  # +7.30 kN in tension, still on the line
    assert not oracle.yielded[+1]


def test_non_monotonic_loading_curve_after_yield_follows_the_dip() -> None:
    """Table 3's dip (23 kN at 0.6 mm, 18 kN at 0.9 mm): past yield the force follows L down the dip
    (e* is the largest elongation, F* the force there, not the largest force); unloading from
    e* = 1.0 runs on the line through (1.0, 18.57)."""
    mat, oracle = gn(TABLE3_LOADING, TABLE2_UNLOADING, 20.0, None)
    path = [(0.0, 0.0), (10.0, 1.0), (13.0, 0.7), (21.0, 1.5), (26.0, 1.0)]
    run = Driven(driven_spring(mat, {"L": TABLE3_LOADING, "U": TABLE2_UNLOADING}, path, 0.05, "mm-ms-kg-kN"))
    run.check_oracle(oracle)
    f_star = 18.0 + 2.0 / 0.35 * 0.1  # L(1.0) = 18.571
    assert run.at(6.0) == run.approx(23.0)
    assert run.at(9.0) == run.approx(18.0)  # below the 20 kN yield, still on L
    assert run.at(10.0) == run.approx(f_star)
    assert run.at(13.0) == run.approx(f_star - 3.0)  # 15.57 (L(0.7) would be 21.33)
    assert run.at(16.0) == run.approx(f_star)  # back at e* on the line
    assert run.at(21.0) == run.approx(35.0)
    assert run.at(26.0) == run.approx(30.0)
