"""The invalid model files of tests/test_bad_input.py: a small valid model (``BASE``, line numbers
below) and the cases (``CASES``) that each edit it into one kind of invalid input, with the line, field
path and expectation the problem line must name."""

from __future__ import annotations

from dataclasses import dataclass, field

BASE = """\
name: bad-input-base
units: SI
curves:
  load: {x: [-0.1, 0.0, 0.1], y: [-1000.0, 0.0, 1000.0]}
  unload: {x: [-0.1, 0.0, 0.1], y: [-2000.0, 0.0, 2000.0]}
  pulse: {x: [0.0, 0.01, 0.02], y: [0.0, 1.0, 0.0]}
nodes:
  ground: {position: [0.0], fixed: true}
  mass: {position: [1.0], mass: 10.0}
springs:
  s1:
    nodes: [ground, mass]
    material: {type: linear_elastic, stiffness: 1.0e5}
initial_velocity: {mass: [-1.0]}
end_time: 0.01
time_step: {safety_factor: 0.5}
output: {interval: 1.0e-4}
"""
# line:  1 name, 2 units, 3 curves, 4 load, 5 unload, 6 pulse, 7 nodes, 8 ground, 9 mass, 10 springs,
#        11 s1, 12 nodes, 13 material, 14 initial_velocity, 15 end_time, 16 time_step, 17 output

GN = "material: {type: general_nonlinear, loading: load, unloading: unload}"


def edit(*pairs: tuple[str, str]) -> str:
    """BASE with each ``old`` replaced once by ``new`` (``old`` must be present)."""
    text = BASE
    for old, new in pairs:
        assert text.count(old) >= 1, old
        text = text.replace(old, new, 1)
    return text


@dataclass
class Case:
    id: str
    text: str
    line: int | None  # exact line of the problem (None: the file as a whole)
    field: str  # dotted field path ("" when the problem has none, e.g. YAML syntax)
    expect: list[str]  # what the message must say (what was expected)
    more: list[tuple[int, str, str]] = field(default_factory=list)  # further (line, field, text) problems


ALIAS_BOMB = "".join(
    f"{chr(97 + k)}: &{chr(97 + k)} [" + ", ".join(["x" if k == 0 else f"*{chr(96 + k)}"] * 10) + "]\n"
    for k in range(9)
)  # a: 10 values, b: 10 x a, ... i: 10^9 values once expanded; the limit (10^6) is passed on line 6 (f)

CASES = [
    Case(
        "yaml-syntax-error",
        edit(("end_time: 0.01", "end_time: 0.01: 0.02")),
        15,
        "",
        ["invalid YAML: mapping values are not allowed here"],
    ),
    # an unclosed brace is detected on the next line; the message names both lines
    Case(
        "yaml-unclosed-flow-mapping",
        edit(("mass: 10.0}", "mass: 10.0")),
        10,
        "",
        ["invalid YAML", "expected ',' or '}'", "flow mapping at line 9"],
    ),
    Case(
        "tab-indentation",
        edit(("    nodes: [ground, mass]", "\tnodes: [ground, mass]")),
        12,
        "",
        ["invalid YAML", "character '\\t'"],
    ),
    Case(
        "duplicate-node-id",
        edit(
            (
                "  mass: {position: [1.0], mass: 10.0}\n",
                "  mass: {position: [1.0], mass: 10.0}\n  mass: {position: [2.0], mass: 5.0}\n",
            )
        ),
        10,
        "nodes.mass",
        ["duplicate key 'mass' (first at line 9)"],
    ),
    Case(
        "duplicate-key-in-mapping",
        edit(("    nodes: [ground, mass]\n", "    nodes: [ground, mass]\n    nodes: [mass, ground]\n")),
        13,
        "springs.s1.nodes",
        ["duplicate key 'nodes' (first at line 12)"],
    ),
    Case(
        "unknown-top-level-key",
        edit(("units: SI", "unit: SI")),
        2,
        "unit",
        ["unknown key 'unit'; did you mean 'units'?"],
    ),
    Case(
        "misspelled-material-key",
        edit(("stiffness: 1.0e5", "stifness: 1.0e5")),
        13,
        "springs.s1.material.stifness",
        ["unknown key 'stifness'; did you mean 'stiffness'?"],
        [(13, "springs.s1.material.stiffness", "missing required field 'stiffness'")],
    ),
    Case(
        "unknown-material-type",
        edit(("linear_elastic", "linear_plastic")),
        13,
        "springs.s1.material",
        [
            "material type 'linear_plastic' is unknown; expected one of 'linear_elastic', 'nonlinear_elastic', "
            "'general_nonlinear', 'crush', 'damper'"
        ],
    ),
    Case(
        "spring-names-unknown-node",
        edit(("[ground, mass]", "[ground, mas]")),
        12,
        "springs.s1.nodes.1",
        ["unknown node 'mas'"],
    ),
    Case(
        "spring-same-node-twice",
        edit(("[ground, mass]", "[mass, mass]")),
        12,
        "springs.s1.nodes",
        ["a spring joins two different nodes"],
    ),
    Case(
        "spring-zero-initial-length",
        edit(("position: [1.0]", "position: [0.0]")),
        12,
        "springs.s1.nodes",
        ["nodes 'ground' and 'mass' are at the same position", "non-zero initial length"],
    ),
    Case(
        "curve-x-not-increasing",
        edit(("x: [-0.1, 0.0, 0.1], y: [-1000.0", "x: [-0.1, 0.1, 0.0], y: [-1000.0")),
        4,
        "curves.load",
        ["x must be strictly increasing (found 0.1 followed by 0.0)"],
    ),
    Case(
        "curve-x-y-length-mismatch",
        edit(("y: [-2000.0, 0.0, 2000.0]", "y: [-2000.0, 0.0]")),
        5,
        "curves.unload",
        ["x and y must have the same number of points (x has 3, y has 2)"],
    ),
    Case(
        "curve-with-one-point",
        edit(("pulse: {x: [0.0, 0.01, 0.02], y: [0.0, 1.0, 0.0]}", "pulse: {x: [0.0], y: [0.0]}")),
        6,
        "curves.pulse.x",
        ["at least 2 items"],
        [(6, "curves.pulse.y", "at least 2 items")],
    ),
    Case(
        "loading-curve-misses-origin",
        edit(
            ("y: [-1000.0, 0.0, 1000.0]", "y: [-900.0, 100.0, 1100.0]"),
            ("material: {type: linear_elastic, stiffness: 1.0e5}", GN),
        ),
        13,
        "springs.s1.material.loading",
        ["the loading curve 'load' must pass through the origin (its force at e=0 is 100)"],
    ),
    Case(
        "unloading-curve-not-increasing",
        edit(
            ("y: [-2000.0, 0.0, 2000.0]", "y: [-2000.0, 0.0, -5.0]"),
            ("material: {type: linear_elastic, stiffness: 1.0e5}", GN),
        ),
        13,
        "springs.s1.material.unloading",
        ["the unloading curve 'unload' must be increasing"],
    ),
    Case(
        "negative-mass",
        edit(("mass: 10.0", "mass: -10.0")),
        9,
        "nodes.mass.mass",
        ["expected greater than 0 (got -10.0)"],
    ),
    Case(
        "missing-mass-on-free-node",
        edit((", mass: 10.0}", "}")),
        9,
        "nodes.mass",
        ["a node that is not fixed in every direction needs 'mass' > 0"],
    ),
    Case(
        "string-where-number-needed",
        edit(("mass: 10.0", "mass: heavy")),
        9,
        "nodes.mass.mass",
        ["expected a valid number (got 'heavy')"],
    ),
    Case(
        "nan-value",
        edit(("stiffness: 1.0e5", "stiffness: .nan")),
        13,
        "springs.s1.material.stiffness",
        ["expected a finite number (got nan)"],
    ),
    Case(
        "inf-value",
        edit(("end_time: 0.01", "end_time: .inf")),
        15,
        "end_time",
        ["expected a finite number (got inf)"],
    ),
    Case(
        "1d-and-2d-positions-mixed",
        edit(("position: [1.0]", "position: [1.0, 0.0]")),
        9,
        "nodes.mass.position",
        ["expected 1 coordinate(s) like the first node", "got 2"],
    ),
    Case(
        "initial-velocity-component-count",
        edit(("{mass: [-1.0]}", "{mass: [-1.0, 0.0]}")),
        14,
        "initial_velocity.mass",
        ["expected 1 component(s), got 2"],
    ),
    Case(
        "time-step-two-modes",
        edit(("{safety_factor: 0.5}", "{safety_factor: 0.5, dt: 1.0e-6}")),
        16,
        "time_step",
        ["give exactly one of safety_factor, dt or tolerance (got safety_factor, dt)"],
    ),
    Case(
        "safety-factor-above-one",
        edit(("safety_factor: 0.5", "safety_factor: 1.5")),
        16,
        "time_step.safety_factor",
        ["expected less than or equal to 1 (got 1.5)"],
    ),
    Case(
        "prescribed-direction-also-fixed",
        edit(
            (
                "end_time: 0.01",
                "prescribed_motion:\n  - {node: ground, quantity: displacement, direction: x, curve: pulse}\n"
                "end_time: 0.01",
            )
        ),
        16,
        "prescribed_motion.0.direction",
        ["node 'ground' is fixed along x: a prescribed direction must not also be fixed"],
    ),
    Case(
        "unknown-curve-in-load",
        edit(("end_time: 0.01", "loads:\n  - {node: mass, force: [100.0], curve: pluse}\nend_time: 0.01")),
        16,
        "loads.0.curve",
        ["unknown curve 'pluse'; defined curves: ['load', 'pulse', 'unload']"],
    ),
    Case(
        "python-object-tag",
        edit(("end_time: 0.01", "end_time: !!python/object/apply:os.system ['true']")),
        15,
        "end_time",
        ["unsupported tag !!python/object/apply:os.system", "expected plain data without tags"],
    ),
    Case("billion-laughs-aliases", ALIAS_BOMB + BASE, 6, "", ["alias bomb", "more than 1,000,000 values"]),
    Case(
        "100-deep-nesting",
        "name: deep\nnodes: " + "[" * 100 + "]" * 100 + "\n",
        2,
        "",
        ["nesting deeper than 64 levels"],
    ),
    Case("empty-file", "", 1, "", ["expected a mapping at top level", "found an empty document"]),
    Case(
        "top-level-is-a-list",
        "- name: a\n- name: b\n",
        1,
        "",
        ["expected a mapping at top level", "found a list"],
    ),
    Case(
        "unknown-history-name",
        edit(
            (
                "output: {interval: 1.0e-4}",
                "output: {interval: 1.0e-4, histories: [spring_force, spring_forse]}",
            )
        ),
        17,
        "output.histories",
        ["unknown history 'spring_forse'", "expected 'all', 'none' or names from"],
    ),
    Case(
        "three-problems-at-once",
        edit(
            ("mass: 10.0", "mass: -10.0"),
            ("stiffness: 1.0e5", "stifness: 1.0e5"),
            ("end_time: 0.01", "end_time: zero"),
        ),
        9,
        "nodes.mass.mass",
        ["expected greater than 0 (got -10.0)"],
        [
            (13, "springs.s1.material.stifness", "did you mean 'stiffness'?"),
            (13, "springs.s1.material.stiffness", "missing required field 'stiffness'"),
            (15, "end_time", "expected a valid number (got 'zero')"),
        ],
    ),
    # metrics: (line 18 "metrics:", its entries from line 19)
    Case(
        "metric-unknown-node",
        BASE + "metrics:\n  - {node: mas, criteria: [hic15]}\n",
        19,
        "metrics.0.node",
        ["unknown node 'mas'", "nodes: ground, mass"],
    ),
    Case(
        "metric-unknown-criterion",
        BASE + "metrics:\n  - {node: mass, criteria: [hic15, hic99]}\n",
        19,
        "metrics.0.criteria.1",
        ["expected 'peak_g', 'hic15', 'hic36'", "(got 'hic99')"],
    ),
    Case(
        "metric-bad-cfc",
        BASE + "metrics:\n  - {node: mass, cfc: 100, criteria: [peak_g]}\n",
        19,
        "metrics.0.cfc",
        ["expected 60, 180, 600 or 1000 (got 100)"],
    ),
    Case(
        "metric-direction-wrong-dimension",
        BASE + "metrics:\n  - {node: mass, direction: [1.0, 0.0], criteria: [olc]}\n",
        19,
        "metrics.0.direction",
        ["expected 1 component(s) (the model is 1-D), got 2"],
    ),
    Case(
        "metric-direction-y-in-1d",
        BASE + "metrics:\n  - {node: mass, direction: y, criteria: [dri]}\n",
        19,
        "metrics.0.direction",
        ["a 1-D model has only the direction 'x'"],
    ),
    Case(
        "metric-direction-zero-vector",
        BASE + "metrics:\n  - {node: mass, direction: [0.0], criteria: [delta_v]}\n",
        19,
        "metrics.0.direction",
        ["the direction must not be the zero vector"],
    ),
    Case(
        "metric-criterion-twice-for-a-node",
        BASE
        + "metrics:\n  - {node: mass, criteria: [hic15]}\n  - {node: mass, cfc: 60, criteria: [peak_g, hic15]}\n",
        20,
        "metrics.1.criteria.1",
        ["criterion 'hic15' of node 'mass' is already asked for in metrics.0"],
    ),
    Case(
        "metric-on-a-fixed-node",
        BASE + "metrics:\n  - {node: ground, criteria: [peak_g]}\n",
        19,
        "metrics.0.node",
        ["node 'ground' is fixed in every direction"],
    ),
    Case(
        "metric-without-criteria",
        BASE + "metrics:\n  - {node: mass}\n",
        19,
        "metrics.0.criteria",
        ["missing required field 'criteria'"],
    ),
    Case(
        "filtered-history-without-metrics",
        edit(
            ("output: {interval: 1.0e-4}", "output: {interval: 1.0e-4, histories: [filtered_acceleration]}")
        ),
        17,
        "output.histories",
        ["'filtered_acceleration' needs a metrics: block"],
    ),
]
