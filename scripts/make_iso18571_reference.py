"""Generates tests/data/iso18571_reference.json: the ISO/TS 18571 scores of the curve pairs of
tests/iso18571_pairs.py by the ``objective-rating-metrics`` package (VSI TU Graz), the independent
implementation crashstudy's :mod:`crashstudy.analysis.iso18571` is tested against.

The package is in crashstudy's ``test`` extra (it pulls ``dtwalign``, seaborn, networkx, shapely); run
the script where it is installed, e.g. ``pip install -e ".[test]" && python scripts/make_iso18571_reference.py``,
or in an environment of its own:

    python3 -m venv /tmp/ormvenv && /tmp/ormvenv/bin/pip install objective-rating-metrics==1.3 scipy
    /tmp/ormvenv/bin/python scripts/make_iso18571_reference.py
"""

from __future__ import annotations

import importlib.metadata
import json
import sys
from pathlib import Path

import numpy as np
from objective_rating_metrics.rating import ISO18571

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from iso18571_pairs import DT, pairs  # noqa: E402


def main() -> None:
    rows = {}
    for name, (test, model) in pairs().items():
        t = np.arange(len(test)) * DT
        iso = ISO18571(np.column_stack([t, test]), np.column_stack([t, model]))  # reference = the test
        rows[name] = {"R": iso.overall_rating(-1), "Z": iso.corridor_rating(-1), "EP": iso.phase_rating(-1),
                      "EM": iso.magnitude_rating(-1), "ES": iso.slope_rating(-1), "shift": int(iso._n_eps),
                      "samples": len(test)}  # fmt: skip
        rows[name] = {k: float(v) if k not in ("shift", "samples") else v for k, v in rows[name].items()}
        print(name, rows[name])
    meta = {"generated_by": "scripts/make_iso18571_reference.py",
            "package": f"objective-rating-metrics {importlib.metadata.version('objective-rating-metrics')}",
            "dtwalign": importlib.metadata.version("dtwalign"), "numpy": np.__version__}  # fmt: skip
    out = ROOT / "tests" / "data" / "iso18571_reference.json"
    out.write_text(json.dumps({"meta": meta, "pairs": rows}, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
