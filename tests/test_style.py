"""The code's form is checked like its behaviour: ``ruff format --check`` and ``ruff check`` over the tree.

The pinned ruff of the test extras formats; a file it would change (or a lint it reports) fails here with ruff's
own list of files, so a formatting drift never lands unnoticed (issue 22: ``ruff format`` adopted).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
TREES = ["src", "tests", "benchmarks"]


@pytest.mark.parametrize("command", [["format", "--check"], ["check"]], ids=["format", "lint"])
def test_ruff_finds_nothing_to_change(command: list[str]) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "ruff", *command, *TREES], cwd=ROOT, capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_no_formatting_exemptions_beyond_a_handful() -> None:
    """At most a handful of ``# fmt: skip`` / ``# fmt: off`` (each with its reason on the line)."""
    marks = []
    for tree in TREES:
        for path in sorted((ROOT / tree).rglob("*.py")):
            if path == Path(__file__).resolve():
                continue
            for k, line in enumerate(path.read_text().splitlines(), 1):
                if "# fmt: skip" in line or "# fmt: off" in line:
                    marks.append(f"{path.relative_to(ROOT)}:{k}: {line.strip()}")
    assert len(marks) <= 5, "\n".join(marks)
