"""What the tests of issue 23 items 5-10 (tests/test_analysis_output_*.py) share: their study.

The study of most tests: a 100 kg body at 3 or 5 m/s on a fixed wall through a linear pad (k) and an
elastoplastic spring in parallel; one zip group moves three paths together. The body is tied to the wall,
so it decelerates while the springs compress and is pulled back (an acceleration along its travel) once
they stretch: the signed pulse changes sign, its resultant does not."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

MODEL = """\
name: tied-body
units: SI
nodes:
  wall: {position: [0.0], fixed: true}
  body: {position: [1.0], mass: 100.0}
springs:
  pad: {nodes: [wall, body], material: {type: linear_elastic, stiffness: 1.0e5}}
  ep: {nodes: [wall, body], material: {type: elastoplastic, stiffness: 2.0e5, tangent_stiffness: 1.0e4, yield_force: 5.0e3}}
initial_velocity: {body: [-4.0]}
end_time: 0.12
output: {interval: 5.0e-4}
metrics:
  - {node: body, cfc: 180, criteria: [peak_g, clip3ms]}
"""
ZIP = {
    "springs.ep.material.yield_force": [4.0e3, 6.0e3],
    "springs.ep.material.tangent_stiffness": [1.0e4, 2.0e4],
    "nodes.body.mass": [100.0, 120.0],
}


@pytest.fixture(scope="module")
def tied(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from crashstudy.run.runner import run_study

    root = tmp_path_factory.mktemp("tied")
    (root / "model.yaml").write_text(MODEL)
    study = {"name": "tied", "model": "model.yaml", "matrix": {"impact_velocity": [3.0, 5.0]}, "zip": [ZIP]}
    (root / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))
    run_study(root / "study.yaml", root / "out")
    return root / "out"
