"""Large models get no generated kernel: its one unrolled function compiles in time and memory that grow
faster than the springs (a 1179-spring grid's compile passed 11 GB before it was stopped), so above
``MAX_GENERATED_SPRINGS`` springs the generic kernel runs the model, even when the generated one is named.

The truth for the compile estimate is the measured cold compiles of benchmarks/results/compile_springs.md
(chains of nonlinear_elastic springs, generated kernel, empty caches): from 16 springs on, where the growth
faster than linear shows, the kernel choice's estimate must be within a factor 2 of each, so a run never
commits to a compile several times longer than it planned for. (The 8-spring chain's 14 CPU s is 2.7 times
the estimate, which is fitted to compile_costs.md's models up to 8 springs, tests/test_kernel_choice.py.)"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from crashstudy.kernel import choice, generated
from crashstudy.kernel.gen_shape import MAX_GENERATED_SPRINGS
from helpers import ROOT, model_batch, run_cli


def chain(n: int) -> dict[str, Any]:
    nodes: dict[str, Any] = {"n0": {"position": [0.0], "fixed": True}}
    springs = {}
    for i in range(1, n + 1):
        nodes[f"n{i}"] = {"position": [0.01 * i], "mass": 1.0}
        springs[f"s{i}"] = {
            "nodes": [f"n{i - 1}", f"n{i}"],
            "material": {"type": "linear_elastic", "stiffness": 1e6},
        }
    return {
        "name": f"chain{n}",
        "nodes": nodes,
        "springs": springs,
        "initial_velocity": {f"n{n}": [-1.0]},
        "end_time": 0.01,
        "output": {"histories": "none"},
    }


def test_a_model_above_the_cap_gets_the_generic_kernel_even_when_the_generated_one_is_named() -> None:
    at, _ = model_batch(chain(MAX_GENERATED_SPRINGS))
    above, _ = model_batch(chain(MAX_GENERATED_SPRINGS + 1))
    assert generated.unsupported(at) is None
    why = generated.unsupported(above)
    assert (
        why is not None
        and f"{MAX_GENERATED_SPRINGS + 1} springs" in why
        and str(MAX_GENERATED_SPRINGS) in why
    )
    assert choice.pick(above, (), None, kernel="generated") == "generic"
    assert choice.pick(at, (), None, kernel="generated") == "generated"


def test_a_run_that_names_the_generated_kernel_for_a_large_model_says_which_kernel_runs_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    model = tmp_path / "chain.yaml"
    model.write_text(yaml.safe_dump({**chain(MAX_GENERATED_SPRINGS + 1), "end_time": 2e-3}))
    monkeypatch.setenv("CRASHSTUDY_KERNEL", "generated")
    done = run_cli("simulate", str(model), "-o", str(tmp_path / "out"))
    assert done.returncode == 0, done.stderr
    assert (
        f"note: the generic kernel runs this model, not the generated one: the model has "
        f"{MAX_GENERATED_SPRINGS + 1} springs"
    ) in done.stderr
    assert "status ok" in done.stdout + done.stderr


def _measured() -> list[tuple[int, float]]:
    text = (ROOT / "benchmarks" / "results" / "compile_springs.md").read_text()
    rows = re.findall(r"^\| (\d+) \| [\d.]+ \| [\d.]+ \| ([\d.]+) \|", text, flags=re.M)
    assert len(rows) >= 4, "benchmarks/results/compile_springs.md lost its table"
    return [(int(n), float(s)) for n, s in rows if int(n) >= 16]


@pytest.mark.parametrize("springs, measured", _measured())
def test_the_compile_estimate_follows_the_measured_growth_with_the_springs(
    springs: int, measured: float
) -> None:
    material = model_batch(chain(springs))[0].material
    estimate = choice.generated_compile_seconds(np.full_like(material, material[0]), 0)
    assert measured / 2 <= estimate <= measured * 2, (springs, estimate, measured)
