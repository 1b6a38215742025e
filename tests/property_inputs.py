"""What the property-based tests (tests/test_properties_*.py) share: ``SMALL_MODEL``, the model their
random studies and compared results are made of, and the count of generated inputs that
actually ran (``COUNTS``), printed at the end of each module by the autouse fixture ``_report_counts``
(each module imports it; the count runs on over the modules of one process, so the last module prints the
total). Run with ``-s`` to see it; docs/robustness.md quotes it.

How many examples each property draws is :func:`strategies.examples`: few in the default profile (the same
derandomized examples on every run, so that CI never fails on a new draw and the suite stays fast; each
test's docstring says how many), and as many as docs/robustness.md's counts, new ones on every run, under
``HYPOTHESIS_PROFILE=explore``."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator

import pytest

COUNTS: Counter[str] = Counter()


@pytest.fixture(scope="module", autouse=True)
def _report_counts() -> Iterator[None]:
    yield
    if COUNTS:
        print(
            "\n[test_properties] generated inputs run: "
            + ", ".join(f"{k}={v}" for k, v in sorted(COUNTS.items()))
        )


# the model of the random studies (3-5) and of the compared results (6)
SMALL_MODEL = """\
name: small
units: SI
curves:
  crush-loading: {x: [-0.2, -0.02, 0.0], y: [-60000.0, -40000.0, 0.0]}
  pulse: {x: [0.0, 0.005, 0.01], y: [0.0, 1.0, 0.0]}
nodes:
  wall:  {position: [0.0], fixed: true}
  front: {position: [0.3], mass: 50.0}
  body:  {position: [0.9], mass: 800.0}
springs:
  crush:
    nodes: [wall, front]
    material: {type: crush, loading: crush-loading, unloading_stiffness: 5.0e6}
  body:
    nodes: [front, body]
    material: {type: linear_elastic, stiffness: 2.0e6}
  damper:
    nodes: [front, body]
    material: {type: damper, damping: 100.0}
initial_velocity: {front: [-10.0], body: [-10.0]}
gravity: [0.0]
loads:
  - {node: body, force: [-100.0], curve: pulse}
end_time: 0.02
time_step: {safety_factor: 0.9}
output: {interval: 1.0e-3, histories: none}
"""
