"""The frontal model's topology and constants, read from frontal-9mass.yaml at import (numba freezes
module-level constants into the compiled code), and the rows of the one block work array. Part of the
hand-specialised reference loop for ``studies/models/frontal-9mass.yaml`` (benchmarks only;
frontal_specialised.py describes it)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numba as nb
import numpy as np

from crashstudy.schema.yamlio import load_yaml

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "models" / "frontal-9mass.yaml"
BLOCK = 256  # variants per block (the generic kernel's BLOCK)
ROW = BLOCK + 8  # row stride of the work array: 33 cache lines, not a power of two (rows 2 KiB apart
# would all fall into the same two L1 sets and alias 4 KiB apart)
N_NODES, N_SPRINGS = 9, 8
SPRING_NODES = ((0, 1), (1, 5), (5, 7), (7, 8), (1, 2), (2, 3), (3, 4), (3, 6))
SPRING_IDS = (
    "crash-box",
    "front-rail",
    "rear-rail",
    "occupant-cell",
    "radiator-support",
    "engine-stackup",
    "engine-mount",
    "gearbox-flange",
)
NODE_IDS = (
    "barrier",
    "bumper",
    "radiator",
    "engine",
    "engine_mount",
    "front_wheel",
    "transmission",
    "aft_frame",
    "survival_room",
)


def _ramp(x: list[float], y: list[float]) -> tuple[float, ...]:
    """Ramp-sum coefficients (y0, s0, x0, x1, ds1, x2, ds2, ...) of a piecewise-linear curve, as
    :func:`crashstudy.arrays.batch.build_batch` computes them (same floating-point operations)."""
    xa = np.asarray(x, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    slope = np.diff(ya) / np.diff(xa)
    ds = np.diff(slope)
    out = [float(ya[0]), float(slope[0]), float(xa[0])]
    for k in range(1, len(xa) - 1):
        out += [float(xa[k]), float(ds[k - 1])]
    return tuple(out)


def _model_constants() -> dict[str, Any]:
    m = load_yaml(str(MODEL)).data  # YAML 1.2 numbers (1.0e6 is a number)
    c = m["curves"]
    sp = m["springs"]
    assert tuple(m["nodes"]) == NODE_IDS and tuple(sp) == SPRING_IDS, (
        "frontal-9mass.yaml changed: update this file"
    )
    for sid, (i, j) in zip(SPRING_IDS, SPRING_NODES, strict=True):
        assert sp[sid]["nodes"] == [NODE_IDS[i], NODE_IDS[j]], sid
    out = {name: _ramp(v["x"], v["y"]) for name, v in c.items()}
    for name in ("cell-unloading", "mount-unloading"):  # straight lines through the origin
        xs, ys = c[name]["x"], c[name]["y"]
        slopes = np.diff(ys) / np.diff(xs)
        assert np.allclose(slopes, slopes[0]) and 0.0 in xs and ys[xs.index(0.0)] == 0.0, name
        out[name + "-slope"] = float(slopes[0])
    for name in ("cell-loading", "mount-loading"):  # monotone: the inverse is a ramp sum too
        xs, ys = c[name]["x"], c[name]["y"]
        assert np.all(np.diff(ys) > 0), name
        out[name + "-inverse"] = _ramp(ys, xs)
    out["ku"] = tuple(
        float(sp[s]["material"]["unloading_stiffness"])
        for s in ("crash-box", "front-rail", "rear-rail", "radiator-support", "engine-stackup")
    )
    cell, mount = sp["occupant-cell"]["material"], sp["engine-mount"]["material"]
    out["cell-yield"] = (float(cell["tension_yield"]), float(cell["compression_yield"]))
    out["mount-yield"] = (float(mount["tension_yield"]), float(mount["compression_yield"]))
    out["k-flange"] = float(sp["gearbox-flange"]["material"]["stiffness"])
    return out


K = _model_constants()
# module-level constants: numba freezes them into the compiled code
C_BOX, C_RAIL, C_REAR, C_RAD, C_ENG = (
    K["crash-box-loading"],
    K["rail-loading"],
    K["rear-rail-loading"],
    K["radiator-support-loading"],
    K["engine-stackup-loading"],
)
C_CELL, C_CELL_INV, C_CELL_U = K["cell-loading"], K["cell-loading-inverse"], K["cell-unloading"]
C_MOUNT, C_MOUNT_INV, C_MOUNT_U = K["mount-loading"], K["mount-loading-inverse"], K["mount-unloading"]
KU_BOX, KU_RAIL, KU_REAR, KU_RAD, KU_ENG = K["ku"]
KU_CELL, KU_MOUNT = K["cell-unloading-slope"], K["mount-unloading-slope"]
YT_CELL, YC_CELL = K["cell-yield"]
YT_MOUNT, YC_MOUNT = K["mount-yield"]
K_FLANGE = K["k-flange"]

_jit = nb.njit(inline="always", error_model="numpy")

# Rows of the one block work array Z (rows x BLOCK columns). One array with a compile-time row
# stride lets LLVM prove that the rows never overlap, so the fused variant loop vectorises without
# runtime alias checks (separately allocated arrays would each need one).
R_U, R_V, R_M, R_IM = 0, 9, 18, 27  # displacement, velocity, mass, 1/mass: 9 rows each
R_DT, R_NST, R_KE0, R_ERR, R_KEEND, R_IEEND = 36, 37, 38, 39, 40, 41
R_FP, R_EP, R_IE, R_PF, R_MC = (
    42,
    50,
    58,
    66,
    74,
)  # per spring: previous F, previous e, work, peak |F|, max crush
R_PA = 82  # per node: peak a^2
R_CS = 91  # crush state (e_min, F*): 2 rows per spring index
R_GS = 107  # general_nonlinear state: 8 rows per slot (slot 0: occupant-cell, slot 1: engine-mount)
R_FH, R_EH, R_UH, R_AH, R_VH, R_KEH, R_IEH = 123, 131, 139, 148, 157, 166, 167  # recorded values
R_YS, R_IX, R_KF = (
    168,
    173,
    178,
)  # per variant: the crush springs' curve scale and 1 / x_scale, the flange's k
N_ROWS = 179
CRUSH_SPRINGS = (0, 1, 2, 4, 5)  # crash-box, front-rail, rear-rail, radiator-support, engine-stackup
