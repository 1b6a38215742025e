"""Environment variables: each one crashstudy reads is listed in crashstudy.environment and a wrong value is
an input error naming the variable and its allowed values (exit 2), never a traceback or silently accepted."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from crashstudy import environment
from crashstudy.errors import InputError
from helpers import ROOT

MODEL = {
    "name": "env-probe",
    "units": "SI",
    "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
    "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 100.0}}},
    "initial_velocity": {"b": [1.0]},
    "end_time": 0.05,
    "output": {"histories": "none"},
}


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("CRASHSTUDY_GEN_BLOCK", "abc"),
        ("CRASHSTUDY_GEN_BLOCK", "0"),
        ("CRASHSTUDY_BACKGROUND_COMPILE", "weird"),
    ],
)
def test_a_wrong_environment_value_is_an_input_error_naming_the_variable(
    tmp_path: Path, name: str, value: str
) -> None:
    """Before: GEN_BLOCK=abc or 0 ended in a ValueError traceback once the generated kernel was imported;
    BACKGROUND_COMPILE=weird ran (exit 0) as if unset."""
    model = tmp_path / "m.yaml"
    model.write_text(yaml.safe_dump(MODEL, sort_keys=False))
    env = dict(os.environ, CRASHSTUDY_KERNEL="generated", CRASHSTUDY_KERNEL_CACHE=str(tmp_path / "kernels"))
    env[name] = value
    done = subprocess.run(
        [sys.executable, "-m", "crashstudy.cli", "simulate", str(model), "-o", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    assert f"environment: {name}: expected {environment.VARIABLES[name][:20]}" in done.stderr
    assert repr(value) in done.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("value", "block"), [("", 256), ("64", 64), (" 1_024 ", 1024), ("65536", 65536)])
def test_gen_block_takes_whole_numbers_in_range(
    monkeypatch: pytest.MonkeyPatch, value: str, block: int
) -> None:
    monkeypatch.setenv("CRASHSTUDY_GEN_BLOCK", value)
    assert environment.gen_block() == block


@pytest.mark.parametrize("value", ["abc", "0", "-3", "2.5", "65537", "1e3"])
def test_gen_block_refuses_what_is_not_a_block_size(monkeypatch: pytest.MonkeyPatch, value: str) -> None:
    monkeypatch.setenv("CRASHSTUDY_GEN_BLOCK", value)
    with pytest.raises(InputError, match="CRASHSTUDY_GEN_BLOCK: expected a whole number"):
        environment.gen_block()


@pytest.mark.parametrize(
    ("value", "mode"),
    [("", "auto"), ("0", "never"), ("OFF", "never"), ("1", "auto"), ("always", "always"), ("true", "auto")],
)
def test_background_compile_values(monkeypatch: pytest.MonkeyPatch, value: str, mode: str) -> None:
    monkeypatch.setenv("CRASHSTUDY_BACKGROUND_COMPILE", value)
    assert environment.background_compile() == mode


def test_every_environment_variable_the_source_names_is_listed_and_checked() -> None:
    """A new variable read anywhere in src/ without an entry here (and a parser) fails this test."""
    named: set[str] = set()
    for path in (ROOT / "src").rglob("*.py"):
        text = path.read_text()
        named |= set(re.findall(r"[\"']((?:CRASHSTUDY|NUMBA)_[A-Z_]+)[\"']", text))
        for read in re.findall(r"(?:os\.environ(?:\.get)?[\[(]|getenv\()\s*([^,)\]]+)", text):
            assert read.strip().startswith(
                ('"', "'", "name", "MAX_VALUES_ENV", "WORK_ENV", "KERNEL_CACHE", "NUMBA_CACHE")
            ), f"{path}: environment read of {read!r}"
    assert named and named <= set(environment.VARIABLES), named - set(environment.VARIABLES)
