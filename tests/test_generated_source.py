"""The generated kernel's source for a two-spring model, kept in tests/golden/two_spring_kernel.py: a
sample of what the generator writes (for a reader of kernel/gen_*.py) and a check that it writes the
same text. A change of the generator that changes this text must bump ``gen_shape.GEN_VERSION`` and
regenerate the file (``python tests/test_generated_source.py``), so that the diff shows what changed.
"""

from __future__ import annotations

import sys
from pathlib import Path

GOLDEN = Path(__file__).parent / "golden" / "two_spring_kernel.py"
TWO_SPRINGS = {  # a bumper on a crush curve against a wall, the body behind it on a linear rail
    "name": "two-springs",
    "curves": {"crush": {"x": [-0.3, -0.05, 0.0, 0.1], "y": [-6.0e4, -4.0e4, 0.0, 1.0e4]}},
    "nodes": {"wall": {"position": [0.0], "fixed": True}, "bumper": {"position": [0.5], "mass": 20.0},
              "body": {"position": [1.5], "mass": 800.0}},
    "springs": {"front": {"nodes": ["wall", "bumper"], "material": {"type": "nonlinear_elastic", "curve": "crush"}},
                "rail": {"nodes": ["bumper", "body"], "material": {"type": "linear_elastic", "stiffness": 2.0e6}}},
    "initial_velocity": {"bumper": [-10.0], "body": [-10.0]}, "end_time": 0.1,
    "output": {"interval": 1.0e-3, "histories": ["spring_force", "kinetic_energy"]},
}  # fmt: skip


def generated_source() -> str:
    from conftest import model_batch
    from crashstudy.kernel.gen_shape import _shape
    from crashstudy.kernel.gen_source import source

    batch, plan = model_batch(TWO_SPRINGS)
    return source(_shape(batch, plan.topology.histories))


def test_generated_source_of_the_two_spring_model_is_the_golden_file() -> None:
    got = generated_source()
    assert got == GOLDEN.read_text(), (
        "the generated source changed: bump GEN_VERSION and regenerate with python tests/test_generated_source.py")
    assert "# generated" not in got and "def run_blocks(" in got


if __name__ == "__main__":  # regenerate the golden file
    sys.path.insert(0, str(Path(__file__).parent))
    GOLDEN.write_text(generated_source())
    print(f"wrote {GOLDEN}")
