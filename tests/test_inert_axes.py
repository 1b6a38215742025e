"""Study axes that cannot mean what they say: one that sets only the mass of a node fixed in every
direction (no equation reads it: refused before anything runs, exit 2), and a matrix axis that lists a
value twice (its variants repeat others: a warning naming the file, line and count).

The truth is the kernel itself: the variants of the refused axis give bit-identical histories (the axis
really changes nothing), while the same axis on the free node changes them (so the check can fail)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from crashstudy.study.plan import load_study
from crashstudy.study.sanity import check_plan
from helpers import run_cli, run_model

MODEL = {
    "name": "anchor-and-body",
    "nodes": {
        "anchor": {"position": [0.0], "fixed": True, "mass": 3.0},
        "body": {"position": [1.0], "mass": 2.0},
    },
    "springs": {
        "s": {"nodes": ["anchor", "body"], "material": {"type": "linear_elastic", "stiffness": 1.0e4}}
    },
    "initial_velocity": {"body": [-1.0]},
    "end_time": 0.2,
    "output": {"histories": ["displacement", "spring_force"]},
}


def _write(tmp_path: Path, matrix: dict[str, list[float]]) -> Path:
    (tmp_path / "model.yaml").write_text(yaml.safe_dump(MODEL))
    study = tmp_path / "study.yaml"
    study.write_text(
        yaml.safe_dump(
            {"name": "inert", "model": "model.yaml", "matrix": matrix},
            sort_keys=False,
            default_flow_style=None,
        )
    )
    return study


def test_the_mass_of_a_fixed_node_changes_no_history_and_its_axis_is_refused(tmp_path: Path) -> None:
    anchor, _, _ = run_model(MODEL, kernel="reference", variants={"nodes.anchor.mass": [3.0, 300.0]})
    body, _, _ = run_model(MODEL, kernel="reference", variants={"nodes.body.mass": [2.0, 200.0]})
    for name in ("displacement", "spring_force"):
        h = anchor.histories[name]
        assert np.array_equal(h[..., 0], h[..., 1]), (
            name
        )  # bit-identical: the anchor's mass enters no equation
    assert not np.allclose(body.histories["displacement"][..., 0], body.histories["displacement"][..., 1])

    study = _write(tmp_path, {"impact_velocity": [1.0, 2.0], "nodes.anchor.mass": [3.0, 300.0]})
    for argv in (["validate", str(study)], ["run", str(study), "-o", str(tmp_path / "out")]):
        done = run_cli(*argv)
        assert done.returncode == 2, done.stderr
        assert f"{study}:5: matrix.nodes.anchor.mass: axis 'nodes.anchor.mass' changes nothing" in done.stderr
        assert "fixed in every direction" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "out").exists()  # refused before anything was written


def test_a_free_nodes_mass_axis_is_not_refused(tmp_path: Path) -> None:
    problems, _ = check_plan(load_study(_write(tmp_path, {"nodes.body.mass": [2.0, 200.0]})))
    assert problems == []


def test_a_matrix_axis_listing_a_value_twice_warns_with_the_count_of_repeated_variants(
    tmp_path: Path,
) -> None:
    study = _write(tmp_path, {"nodes.body.mass": [2.0, 4.0, 2.0], "impact_velocity": [1.0, 2.0]})
    done = run_cli("validate", str(study))
    assert done.returncode == 0, done.stderr
    # 3 masses x 2 speeds: the third mass repeats the first, so 2 of the 6 variants repeat others
    assert (
        f"{study}:4: matrix.nodes.body.mass: lists 2 (2 times): 2 of the 6 variants repeat others"
        in done.stderr
    )
    out, _, _ = run_model(MODEL, kernel="reference", variants={"nodes.body.mass": [2.0, 4.0, 2.0]})
    d = out.histories["displacement"]
    assert np.array_equal(d[..., 0], d[..., 2]) and not np.array_equal(
        d[..., 0], d[..., 1]
    )  # the warning's claim, checked
