"""The ``metrics:`` block's inputs and reruns: bad metrics in a study's ``set`` exit 2 at their own line,
the schema and result tables name every criterion, ``validate`` warns when the step is too long for the
filter class, and a rerun reuses finished variants with their criteria and notes.

The truth, a half-sine pulse imposed exactly with prescribed acceleration whose criteria have closed forms,
is described in half_sine_sled.py."""

from __future__ import annotations

from pathlib import Path

import pytest

from crashstudy.cli.main import main
from half_sine_sled import pulse_model


def test_bad_metrics_in_a_study_set_exit_2_at_their_own_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    study = (
        "name: s\nmodel: m.yaml\nmatrix:\n  curves.pulse.scale: [0.5, 1.0]\nset:\n  metrics:\n"
        "    - {node: sled, criteria: [peak_g]}\n    - node: sledd\n      criteria: [hic15]\n"
        "      direction: [1.0, 0.0]\n"
    )
    (tmp_path / "m.yaml").write_text(pulse_model())
    (tmp_path / "s.yaml").write_text(study)
    for argv in (
        ["validate", str(tmp_path / "s.yaml")],
        ["run", str(tmp_path / "s.yaml"), "-o", str(tmp_path / "o")],
    ):
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "Traceback" not in err
        assert (
            f"{tmp_path / 's.yaml'}:8: set.metrics.1.node: after 'set' the model is invalid: unknown node 'sledd'"
            in err
        )
        assert (
            f"{tmp_path / 's.yaml'}:10: set.metrics.1.direction: after 'set' the model is invalid: expected 1 "
            "component(s) (the model is 1-D), got 2"
        ) in err


def test_schema_and_result_tables_name_every_criterion_of_the_maths() -> None:
    from typing import get_args

    from crashstudy.metrics import criteria
    from crashstudy.metrics.record import METRIC_META
    from crashstudy.schema.model import CRITERION_NAMES, Criterion

    assert CRITERION_NAMES == criteria.CRITERIA == get_args(Criterion)
    assert set(METRIC_META) == set(criteria.CRITERIA) | {e for x in criteria.EXTRA.values() for e in x}


def test_a_rerun_reuses_finished_variants_with_their_criteria_and_notes(tmp_path: Path) -> None:
    """A variant copied from an earlier result keeps its criteria and its note (the note is an index
    into a table of texts: it is re-coded into the new file's table, not copied as a number)."""
    from crashstudy.run.runner import run_study

    (tmp_path / "m.yaml").write_text(pulse_model(extra="output: {interval: 1.0e-3}\n"))
    study = "name: s\nmodel: m.yaml\nmatrix:\n  time_step.dt: [{}]\n"
    (tmp_path / "s.yaml").write_text(study.format("2.0e-4"))  # 5 kHz: below 10 x CFC 1000, a note
    first = run_study(tmp_path / "s.yaml", tmp_path / "o").summary
    note = first["criteria_note"][0]
    assert note.startswith("sled: ") and "10 x CFC" in note
    (tmp_path / "s.yaml").write_text(study.format("1.0e-5, 2.0e-4"))  # a new variant first, no note
    from crashstudy.run.runner import run_plan
    from crashstudy.study.plan import load_study

    report = run_plan(load_study(tmp_path / "s.yaml"), tmp_path / "o")
    assert (report.n_reused, report.n_computed) == (1, 1)
    second = report.results.summary
    assert list(second["criteria_note"]) == ["", note]
    assert second["hic15.sled"][1] == first["hic15.sled"][0]


def test_validate_warns_when_the_step_is_too_long_for_the_filter_class(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = tmp_path / "coarse.yaml"
    model.write_text(pulse_model(extra="output: {interval: 1.0e-3}\n").replace("dt: 1e-05", "dt: 0.0002"))
    capsys.readouterr()
    assert main(["validate", str(model)]) == 0
    err = capsys.readouterr().err
    # dt = 0.2 ms: 5 kHz, half the 10 kHz (10 x CFC 1000) SAE J211-1 asks for
    assert "metrics.0.cfc: CFC 1000 asks for a sample rate of 10000 Hz, the time step gives 5000 Hz" in err
    model.write_text(pulse_model())  # dt = 10 us: 100 kHz
    assert main(["validate", str(model)]) == 0
    assert "metrics" not in capsys.readouterr().err
