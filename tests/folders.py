"""The inputs of the result-folder tests (a model, a study, an optimize and a calibrate study and its
data) and a snapshot of a folder's files (tests/test_write_read.py, tests/test_untrusted_files.py)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

MODEL = {
    "name": "wr",
    "units": "SI",
    "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
    "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 100.0}}},
    "initial_velocity": {"b": [1.0]},
    "end_time": 0.05,
    "output": {"interval": 0.001, "histories": ["spring_force"]},
}
MASSES = [1.0, 2.0, 4.0]


def peak_force(m: float) -> float:
    """Closed form: the force rises for all of 0.05 s (a quarter period is >= 0.157 s)."""
    return float(np.sqrt(100.0 * m) * np.sin(0.05 * np.sqrt(100.0 / m)))


def files(tmp: Path) -> dict[str, Path]:
    """Model, a study ('precious'), an optimize and a calibrate study and its data (m = 2 kg)."""
    (tmp / "model.yaml").write_text(yaml.safe_dump(MODEL, sort_keys=False))
    out = {"model": tmp / "model.yaml"}
    studies = {
        "study": {"name": "precious", "model": "model.yaml", "matrix": {"nodes.b.mass": MASSES}},
        "other": {"name": "other", "model": "model.yaml", "matrix": {"nodes.b.mass": [3.0, 5.0, 6.0]}},
        "opt": {
            "name": "opt",
            "model": "model.yaml",
            "optimize": {
                "minimize": "peak_force.s",
                "variables": {"nodes.b.mass": [1.0, 4.0]},
                "budget": 30,
                "seed": 1,
            },
        },
        "cal": {
            "name": "cal",
            "model": "model.yaml",
            "calibrate": {
                "data": "data.csv",
                "channel": {"quantity": "spring_force", "spring": "s"},
                "variables": {"nodes.b.mass": [1.0, 4.0]},
            },
        },
    }
    for key, body in studies.items():
        out[key] = tmp / f"{key}.yaml"
        out[key].write_text(yaml.safe_dump(body, sort_keys=False))
    t = np.linspace(0.0, 0.05, 51)
    pd.DataFrame({"time": t, "value": np.sqrt(200.0) * np.sin(t * np.sqrt(50.0))}).to_csv(
        tmp / "data.csv", index=False
    )
    return out


def snapshot(folder: Path) -> dict[str, tuple[int, int, int]]:
    out = {}
    for root, _, names in os.walk(folder):
        for n in names:
            st = os.lstat(Path(root) / n)
            out[str((Path(root) / n).relative_to(folder))] = (st.st_ino, st.st_mtime_ns, st.st_size)
    return out
