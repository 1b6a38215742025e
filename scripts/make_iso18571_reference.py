"""Generates tests/data/iso18571_reference.json: the ISO/TS 18571 scores of the curve pairs of
tests/iso18571_pairs.py by the ``objective-rating-metrics`` package (VSI TU Graz), the independent
implementation crashstudy's :mod:`crashstudy.analysis.iso18571` is tested against, with a fingerprint of each
pair's samples (tests/test_iso18571.py checks that the committed scores are of these very samples).

``--check`` rates every pair again and compares with the committed file (every score within 1e-12, the
same shift): exit 0 when the file is the installed package's output, 1 otherwise. The test suite does not
run the package itself (its first rating compiles dtwalign's numba functions: ~12 CPU s).

The package is in crashstudy's ``test`` extra (it pulls ``dtwalign``, seaborn, networkx, shapely); run
the script where it is installed, e.g. ``pip install -e ".[test]" && python scripts/make_iso18571_reference.py``,
or in an environment of its own:

    python3 -m venv /tmp/ormvenv && /tmp/ormvenv/bin/pip install objective-rating-metrics==1.3 scipy
    /tmp/ormvenv/bin/python scripts/make_iso18571_reference.py [--check]
"""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
from objective_rating_metrics.rating import ISO18571

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from iso18571_pairs import DT, fingerprint, pairs  # noqa: E402

OUT = ROOT / "tests" / "data" / "iso18571_reference.json"
SCORES = ("R", "Z", "EP", "EM", "ES")


def rate_all() -> dict[str, dict[str, Any]]:
    rows: dict[str, dict[str, Any]] = {}
    for name, (test, model) in pairs().items():
        t = np.arange(len(test)) * DT
        iso = ISO18571(np.column_stack([t, test]), np.column_stack([t, model]))  # reference = the test
        rows[name] = {"R": iso.overall_rating(-1), "Z": iso.corridor_rating(-1), "EP": iso.phase_rating(-1),
                      "EM": iso.magnitude_rating(-1), "ES": iso.slope_rating(-1)}  # fmt: skip
        rows[name] = {k: float(v) for k, v in rows[name].items()}
        rows[name] |= {
            "shift": int(iso._n_eps),
            "samples": len(test),
            "fingerprint": fingerprint(test, model),
        }
        print(name, rows[name])
    return rows


def _same(new: dict[str, Any] | None, old: dict[str, Any] | None) -> bool:
    if new is None or old is None:
        return False
    return new["shift"] == old["shift"] and all(abs(new[k] - old[k]) <= 1e-12 for k in SCORES)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="compare with the committed file, write nothing")
    check = ap.parse_args().check
    rows = rate_all()
    if check:
        committed = json.loads(OUT.read_text())["pairs"]
        bad = [
            name for name in rows.keys() | committed.keys() if not _same(rows.get(name), committed.get(name))
        ]
        print(f"{OUT}: " + (f"differs from the package's output: {bad}" if bad else "the package's output"))
        return 1 if bad else 0
    meta = {"generated_by": "scripts/make_iso18571_reference.py",
            "package": f"objective-rating-metrics {importlib.metadata.version('objective-rating-metrics')}",
            "dtwalign": importlib.metadata.version("dtwalign"), "numpy": np.__version__}  # fmt: skip
    OUT.write_text(json.dumps({"meta": meta, "pairs": rows}, indent=1) + "\n")
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
