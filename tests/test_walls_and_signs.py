"""Issue 23 items 1 and 2 (and issue 24 item 10, the 2-D wall case): physically impossible inputs are refused.

1. A node that starts on the wrong side of a rigid wall it is listed in (a wall point typed in mm in an SI
   model) was valid and ran to 44,155 g (1-D) or "numerical instability" (2-D). Now ``validate``,
   ``simulate`` and ``run`` exit 2 naming the wall's point line, the node and how far behind it starts;
   a study axis that moves a wall or a node behind it is refused at the offending value.
2. A ``nonlinear_elastic`` curve or ``general_nonlinear`` loading curve whose force has the sign opposite
   to the elongation (a negative stiffness) was valid and ran to 411,926 g. Now refused naming the curve
   and the offending point, also for a study axis value that flips a point's sign.

The truth of each case is arithmetic on the input (the signed distance to the plane; the sign of x*y).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from crashstudy.schema.signs import depth_behind_walls, wrong_sign_points
from helpers import run_main

WALL_1D = """\
name: wall1d
units: SI
nodes:
  m1: {position: [1.5], mass: 4000.0}
  m2: {position: [3.0], mass: 2000.0}
springs:
  s: {nodes: [m1, m2], material: {type: linear_elastic, stiffness: 1.0e7}}
initial_velocity: {m1: [-15.6], m2: [-15.6]}
rigid_walls:
  - {id: wall, point: [1500.0], normal: [1.0]}
end_time: 0.05
output: {histories: none}
"""
# line 10: the wall

WALL_2D = """\
name: wall2d
units: SI
nodes:
  m1: {position: [1.5, 0.2], mass: 4000.0}
  m2: {position: [3.0, 0.2], mass: 2000.0}
springs:
  s: {nodes: [m1, m2], material: {type: linear_elastic, stiffness: 1.0e7}}
initial_velocity: {m1: [-15.6, 0.0], m2: [-15.6, 0.0]}
rigid_walls:
  - {id: floor, point: [0.0, 0.0], normal: [0.0, 1.0]}
  - {id: wall, point: [1500.0, 0.0], normal: [2.0, 0.0]}
end_time: 0.05
output: {histories: none}
"""
# line 11: the second wall

CURVE = """\
name: curve
units: SI
curves:
  load: {x: [-0.5, 0.0, 0.5], y: [2.0e5, 0.0, 2.0e5]}
  unload: {x: [-0.01, 0.0, 0.01], y: [-1.0e6, 0.0, 1.0e6]}
nodes:
  base: {position: [0.0], fixed: true}
  m1: {position: [1.0], mass: 1000.0}
springs:
  s: {nodes: [base, m1], material: {type: general_nonlinear, loading: load, unloading: unload}}
initial_velocity: {m1: [-10.0]}
end_time: 0.05
output: {histories: none}
"""
# line 10: the spring


def run(*argv: str) -> tuple[int, str]:
    """``crashstudy ARGV`` in this process: (exit code, stderr)."""
    rc, _, err = run_main(*argv)
    return rc, err


def write(tmp: Path, name: str, text: str) -> Path:
    p = tmp / name
    p.write_text(text, encoding="utf-8")
    return p


@pytest.mark.parametrize(("text", "line", "wall"), [(WALL_1D, 10, 0), (WALL_2D, 11, 1)], ids=["1-D", "2-D"])
@pytest.mark.parametrize("command", ["validate", "simulate"])
def test_a_node_behind_a_wall_is_refused_naming_the_wall_the_node_and_the_distance(
    tmp_path: Path, text: str, line: int, wall: int, command: str
) -> None:
    model = write(tmp_path, "m.yaml", text)
    rc, err = run(command, str(model), *(["-o", str(tmp_path / "out")] if command == "simulate" else []))
    assert rc == 2, err
    assert "Traceback" not in err
    # 1500 - 1.5 = 1498.5 m along the (normalised) wall normal; m2 is behind too
    assert (
        f"{model}:{line}: rigid_walls.{wall}.point: node 'm1' starts 1498.5 m behind wall 'wall' (and 1 more"
        in err
    )
    assert "floor" not in err  # both nodes are 0.2 m above the floor: on its front side
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_a_study_axis_that_moves_a_wall_or_a_node_behind_it_is_refused_at_that_value(tmp_path: Path) -> None:
    write(tmp_path, "m.yaml", WALL_1D.replace("point: [1500.0]", "point: [0.0]"))
    study = write(
        tmp_path,
        "s.yaml",
        "name: s\nmodel: m.yaml\nmatrix:\n  rigid_walls.0.point.0: [0.0, 1.0, 1500.0]\n"
        "zip:\n  - {nodes.m2.position.0: [2.0, -2.0]}\n",
    )
    rc, err = run("validate", str(study))
    assert rc == 2, err
    assert (
        f"{study}:4: matrix.rigid_walls.0.point.0.2: value 1500.0 makes the model invalid: node 'm1' starts "
        "1498.5 m behind wall 'wall'" in err
    )
    assert "point.0.1" not in err  # 1.0 is 0.5 m in front of m1
    assert (
        "zip.0.nodes.m2.position.0.1: value -2.0 makes the model invalid: node 'm2' starts 2 m behind" in err
    )
    rc, err = run("run", str(study), "--dry-run")
    assert rc == 2 and "1498.5 m behind wall" in err, err


def test_nodes_a_wall_does_not_stop_or_that_cannot_move_into_it_may_start_behind_it(tmp_path: Path) -> None:
    text = (
        WALL_1D.replace("m1: {position: [1.5], mass: 4000.0}", "m1: {position: [1.5], fixed: true}")
        .replace("initial_velocity: {m1: [-15.6], m2: [-15.6]}", "initial_velocity: {m2: [-15.6]}")
        .replace("normal: [1.0]}", "normal: [1.0], nodes: [m1]}")
    )
    assert run("validate", str(write(tmp_path, "a.yaml", text)))[0] == 0
    on_plane = WALL_1D.replace("point: [1500.0]", "point: [1.5]")
    assert run("validate", str(write(tmp_path, "b.yaml", on_plane)))[0] == 0


def test_the_distance_behind_a_wall_is_the_signed_distance_along_the_unit_normal() -> None:
    """Closed form: node (3, 4), wall through the origin with normal (-3, -4) (length 5): 5 behind."""
    x = np.array([[3.0, 4.0], [-3.0, -4.0]])[:, :, None]
    free = np.array([[True, True], [True, True]])
    point, normal = np.zeros((1, 2, 1)), np.array([[-3.0, -4.0]])[:, :, None]
    depth = depth_behind_walls(x, free, point, normal, np.array([[True, True]]))
    assert depth[0, :, 0] == pytest.approx([5.0, 0.0], rel=1e-15)
    fixed_x = np.array([[False, True], [True, True]])  # moves only along y, the normal has a y part
    assert depth_behind_walls(x, fixed_x, point, normal, np.array([[True, True]]))[0, 0, 0] == pytest.approx(
        5.0
    )


@pytest.mark.parametrize("command", ["validate", "simulate"])
def test_a_loading_curve_of_the_wrong_sign_is_refused_naming_the_curve_and_the_point(
    tmp_path: Path, command: str
) -> None:
    model = write(tmp_path, "m.yaml", CURVE)
    rc, err = run(command, str(model), *(["-o", str(tmp_path / "out")] if command == "simulate" else []))
    assert rc == 2, err
    assert (
        f"{model}:10: springs.s.material.loading: the general_nonlinear loading curve 'load' has force 200000 "
        "at x = -0.5 (point 0): in compression (x < 0) its force must be <= 0"
    ) in err


def test_a_nonlinear_elastic_curve_of_the_wrong_sign_in_tension_is_refused(tmp_path: Path) -> None:
    text = CURVE.replace("y: [2.0e5, 0.0, 2.0e5]", "y: [-2.0e5, 0.0, -1.0e3]").replace(
        "{type: general_nonlinear, loading: load, unloading: unload}",
        "{type: nonlinear_elastic, curve: load}",
    )
    rc, err = run("validate", str(write(tmp_path, "m.yaml", text)))
    assert (
        rc == 2
        and "the nonlinear_elastic curve 'load' has force -1000 at x = 0.5 (point 2): in tension" in err
    )


def test_a_tension_free_curve_is_legal(tmp_path: Path) -> None:
    """Zero force on one side is of no sign: a compression-only contact spring stays valid."""
    text = CURVE.replace("y: [2.0e5, 0.0, 2.0e5]", "y: [-2.0e5, 0.0, 0.0]").replace(
        "{type: general_nonlinear, loading: load, unloading: unload}",
        "{type: nonlinear_elastic, curve: load}",
    )
    assert run("validate", str(write(tmp_path, "m.yaml", text)))[0] == 0


def test_a_study_axis_that_flips_a_curve_point_is_refused_at_that_value(tmp_path: Path) -> None:
    write(tmp_path, "m.yaml", CURVE.replace("y: [2.0e5, 0.0, 2.0e5]", "y: [-2.0e5, 0.0, 2.0e5]"))
    study = write(tmp_path, "s.yaml", "name: s\nmodel: m.yaml\nmatrix:\n  curves.load.y.0: [-3.0e5, 1.0e5]\n")
    rc, err = run("validate", str(study))
    assert rc == 2, err
    assert (
        f"{study}:4: matrix.curves.load.y.0.1: value 100000.0 makes the model invalid: the general_nonlinear "
        "loading curve 'load' has force 100000 at x = -0.5 (point 0)"
    ) in err
    assert "y.0.0" not in err


def test_wrong_sign_points_closed_form() -> None:
    xs = np.array([[-1.0], [0.0], [1.0], [2.0]])
    ys = np.array([[1e-12], [0.0], [-5.0], [3.0]])  # 1e-12 of a curve peaking at 5: round-off, not a sign
    assert wrong_sign_points(xs, ys)[:, 0].tolist() == [False, False, True, False]
