"""Every kind of invalid input file exits with code 2 and a short message naming file, line and field.

Each case edits a small valid model (``BASE``; the cases are in bad_model_cases.py) and runs ``crashstudy
validate`` and ``crashstudy simulate -o DIR`` on it. Both must exit 2 and print to stderr, without a
traceback and on less than 40 lines, a problem line ``<file>:<line>: <field path>: <message>`` where the
line is the exact line of the offending text, the field path is the dotted path of the offending field, and
the message says what was expected; ``simulate`` must leave its output folder empty.

Most checks call :func:`crashstudy.cli.main` in-process (fast); a few run the real command line in a
subprocess, as a user would. Invalid study files and the example files of ``studies/`` are checked here
too."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import pytest

from bad_model_cases import BASE, CASES, Case, edit
from crashstudy.cli.main import main
from helpers import STUDIES, run_cli_process


def problem_lines(err: str, path: Path) -> list[str]:
    return [ln for ln in err.splitlines() if ln.startswith(str(path))]


def assert_reported(err: str, path: Path, line: int | None, fld: str, expect: list[str]) -> None:
    """``err`` has a problem line ``<path>:<line>: <field>: ...`` saying each of ``expect``."""
    where = f"{path}:{line}:" if line is not None else f"{path}:"
    head = f"{where} {fld}: " if fld else f"{where} "
    hits = [ln for ln in problem_lines(err, path) if ln.startswith(head)]
    assert hits, f"no problem line starting with {head!r} in:\n{err}"
    assert any(all(text in ln for text in expect) for ln in hits), f"{expect} not said in {hits}"


def assert_short_and_clean(err: str, out: str = "") -> None:
    assert "Traceback" not in err and "Traceback" not in out
    assert err.startswith("error: invalid input\n"), err
    assert len(err.splitlines()) < 40
    assert out == ""


def cli(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    capsys.readouterr()
    rc = main(list(argv))
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def assert_nothing_written(out_dir: Path) -> None:
    assert not out_dir.exists() or not any(out_dir.iterdir()), sorted(out_dir.rglob("*"))


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_invalid_model_exits_2_naming_file_line_field_and_expectation(
    case: Case, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / f"{case.id}.yaml"
    path.write_text(case.text, encoding="utf-8")
    out_dir = tmp_path / "results"
    for argv in (["validate", str(path)], ["simulate", str(path), "-o", str(out_dir)]):
        rc, out, err = cli(capsys, *argv)
        assert rc == 2, (argv, out, err)
        assert_short_and_clean(err, out)
        assert_reported(err, path, case.line, case.field, case.expect)
        for line, fld, text in case.more:
            assert_reported(err, path, line, fld, [text])
        assert len(problem_lines(err, path)) == 1 + len(case.more), err  # every problem once, nothing else
    assert_nothing_written(out_dir)


def test_missing_file_exits_2_naming_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "no-such-model.yaml"
    for argv in (["validate", str(path)], ["simulate", str(path), "-o", str(tmp_path / "results")]):
        rc, out, err = cli(capsys, *argv)
        assert rc == 2
        assert_short_and_clean(err, out)
        assert err.splitlines()[1] == f"{path}: file not found"
    assert_nothing_written(tmp_path / "results")


def test_shape_and_relational_problems_are_reported_together(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``validate`` reports every problem at once: here a negative mass (a field's own
    range), a spring naming an unknown node and a load naming an unknown curve (relations)."""
    path = tmp_path / "mixed.yaml"
    path.write_text(
        edit(
            ("mass: 10.0", "mass: -10.0"),
            ("[ground, mass]", "[ground, mas]"),
            ("end_time: 0.01", "loads:\n  - {node: mass, force: [1.0], curve: pluse}\nend_time: 0.01"),
        )
    )
    rc, out, err = cli(capsys, "validate", str(path))
    assert rc == 2
    assert_reported(err, path, 9, "nodes.mass.mass", ["expected greater than 0 (got -10.0)"])
    assert_reported(err, path, 12, "springs.s1.nodes.1", ["unknown node 'mas'"])
    assert_reported(err, path, 16, "loads.0.curve", ["unknown curve 'pluse'"])


def test_validate_refuses_a_fixed_dt_above_the_critical_step_like_simulate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """k = 1e7 N/m, m = 10 kg: dt_crit = 2 / sqrt(2 k / m) = 1.41e-3 s (a little less with a safety
    margin); dt = 5e-3 s is refused."""
    path = tmp_path / "dt.yaml"
    path.write_text(
        edit(
            ("stiffness: 1.0e5", "stiffness: 1.0e7"),
            ("end_time: 0.01", "end_time: 0.05"),
            ("{safety_factor: 0.5}", "{dt: 5.0e-3}"),
            ("interval: 1.0e-4", "interval: 1.0e-2"),
        )
    )
    rc, out, err = cli(capsys, "simulate", str(path), "-o", str(tmp_path / "results"))
    assert rc == 2
    assert_reported(err, path, 16, "time_step.dt", ["dt=0.005 is above the critical step dt_crit=0.001"])
    assert_nothing_written(tmp_path / "results")
    rc, out, err = cli(capsys, "validate", str(path))
    assert rc == 2, out
    assert_reported(err, path, 16, "time_step.dt", ["dt=0.005 is above the critical step dt_crit=0.001"])


# --------------------------------------------------------------------------------------------------
# Study files (docs/format.md)
# --------------------------------------------------------------------------------------------------


@dataclass
class StudyCase:
    id: str
    text: str
    file: str  # which file the problem is reported in: "study" or "model"
    line: int | None
    field: str
    expect: list[str]


STUDY_CASES = [
    StudyCase(
        "unknown-axis-path",
        "name: s\nmodel: model.yaml\nmatrix:\n  impact_velocity: [1.0, 2.0]\n"
        "  springs.s1.material.stifness: [1.0e5, 2.0e5]\n",
        "study",
        5,
        "matrix.springs.s1.material.stifness",
        ["unknown axis 'springs.s1.material.stifness'", "closest valid paths: springs.s1.material.stiffness"],
    ),
    StudyCase(
        "unknown-axis-path-several-close",
        "name: s\nmodel: model.yaml\nmatrix:\n  nodes.mass.mas: [5.0, 10.0]\n",
        "study",
        4,
        "matrix.nodes.mass.mas",
        ["closest valid paths: nodes.mass.mass, nodes.mass.position.0, nodes.ground.mass"],
    ),
    StudyCase(
        "zip-group-unequal-lengths",
        "name: s\nmodel: model.yaml\nzip:\n"
        "  - {nodes.mass.mass: [5.0, 10.0], impact_velocity: [1.0, 2.0, 3.0]}\n",
        "study",
        4,
        "zip.0",
        ["the axes of a zip group need equal lengths, got [2, 3]"],
    ),
    StudyCase(
        "matrix-value-makes-model-invalid",
        "name: s\nmodel: model.yaml\nmatrix:\n  nodes.mass.mass:\n    - 5.0\n    - -10.0\n    - 20.0\n",
        "study",
        6,
        "matrix.nodes.mass.mass.1",
        ["value -10.0 makes the model invalid", "greater than 0"],
    ),
    StudyCase(
        "model-file-does-not-exist",
        "name: s\nmodel: models/nothere.yaml\nmatrix:\n  nodes.mass.mass: [5.0]\n",
        "study",
        2,
        "model",
        ["model file not found", "nothere.yaml"],
    ),
    StudyCase(
        "unknown-study-key",
        "name: s\nmodel: model.yaml\nmatrx:\n  nodes.mass.mass: [5.0]\n",
        "study",
        3,
        "matrx",
        ["unknown key 'matrx'; did you mean 'matrix'?"],
    ),
    StudyCase(
        "invalid-model-of-a-study",
        "name: s\nmodel: model.yaml\n",
        "model",
        9,
        "nodes.mass.mass",
        ["expected a valid number (got 'heavy')"],
    ),
]


@pytest.mark.parametrize("case", STUDY_CASES, ids=[c.id for c in STUDY_CASES])
def test_invalid_study_exits_2_naming_file_line_field_and_expectation(
    case: StudyCase, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = tmp_path / "model.yaml"
    model.write_text(edit(("mass: 10.0", "mass: heavy")) if case.file == "model" else BASE)
    study = tmp_path / f"{case.id}.yaml"
    study.write_text(case.text)
    named = study if case.file == "study" else model
    out_dir = tmp_path / "results"
    for argv in (["validate", str(study)], ["run", str(study), "-o", str(out_dir)]):
        rc, out, err = cli(capsys, *argv)
        assert rc == 2, (argv, out, err)
        assert_short_and_clean(err, out)
        assert_reported(err, named, case.line, case.field, case.expect)
    assert_nothing_written(out_dir)


# --------------------------------------------------------------------------------------------------
# Valid files, and the real command line in a subprocess
# --------------------------------------------------------------------------------------------------

EXAMPLE_MODELS = sorted((STUDIES / "models").glob("*.yaml"))
EXAMPLE_STUDIES = sorted(STUDIES.glob("*.yaml"))


@pytest.mark.parametrize("path", EXAMPLE_MODELS + EXAMPLE_STUDIES, ids=lambda p: str(p.relative_to(STUDIES)))
def test_example_files_validate(path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc, out, err = cli(capsys, "validate", str(path))
    assert rc == 0, err
    assert err == ""
    kind = "model" if path.parent.name == "models" else "study"
    assert re.fullmatch(rf"{re.escape(str(path))}: valid {kind} \(.*\)\n", out), out


def test_example_models_are_present() -> None:
    names = {p.name for p in EXAMPLE_MODELS}
    assert {
        "general-nonlinear-tension.yaml",
        "general-nonlinear-compression.yaml",
        "helicopter-subfloor.yaml",
        "linear-spring.yaml",
        "nonlinear-elastic.yaml",
    } <= names


def test_command_line_in_a_subprocess(tmp_path: Path) -> None:
    """The installed command line as a user runs it: paths relative to the working directory are
    reported as given; exit codes 2 (invalid) and 0 (valid); ``run --dry-run`` prints the count."""
    (tmp_path / "broken.yaml").write_text(edit(("mass: 10.0}", "mass: 10.0")))
    (tmp_path / "tagged.yaml").write_text(
        edit(("end_time: 0.01", "end_time: !!python/object/apply:os.system ['true']"))
    )
    (tmp_path / "model.yaml").write_text(BASE)
    (tmp_path / "study.yaml").write_text(
        "name: s\nmodel: model.yaml\nmatrix:\n  nodes.mass.mass: [5.0, 10.0, 20.0]\n  impact_velocity: [1.0, 2.0]\n"
        "zip:\n  - {springs.s1.material.stiffness: [1.0e5, 2.0e5], end_time: [0.01, 0.02]}\n"
    )

    p = run_cli_process("validate", "broken.yaml", cwd=tmp_path)
    assert p.returncode == 2 and p.stdout == "" and "Traceback" not in p.stderr
    assert p.stderr.splitlines()[1].startswith("broken.yaml:10: invalid YAML: expected ',' or '}'")
    assert len(p.stderr.splitlines()) < 40

    p = run_cli_process("simulate", "tagged.yaml", "-o", "out", cwd=tmp_path)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.splitlines()[1].startswith(
        "tagged.yaml:15: end_time: unsupported tag !!python/object/apply"
    )
    assert_nothing_written(tmp_path / "out")

    p = run_cli_process("run", "study.yaml", "--dry-run", "-o", "out", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert p.stdout.splitlines()[0] == "study s: 12 variants (3 x 2 x 2)"
    assert_nothing_written(tmp_path / "out")

    p = run_cli_process("validate", "study.yaml", cwd=tmp_path)
    assert p.returncode == 0 and p.stdout == "study.yaml: valid study (12 variants)\n", p.stderr


def test_dry_run_lists_axis_values_as_plain_numbers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "model.yaml").write_text(BASE)
    study = tmp_path / "study.yaml"
    study.write_text("name: s\nmodel: model.yaml\nmatrix:\n  nodes.mass.mass: [5.0, 10.0, 20.0]\n")
    rc, out, err = cli(capsys, "run", str(study), "--dry-run")
    assert rc == 0
    assert out.splitlines() == ["study s: 3 variants (3)", "  nodes.mass.mass: 3 values [5.0, 10.0, 20.0]"]
