"""What a new user trips over (issue 13 items 1, 2, 5, 7): data loss, silent mistakes, the summary
table, help texts and messages.

The model is the 1-D frontal impact of test_study_*.py: a crush spring (wall - front, unloading stiffness
5e6 N/m) and a linear spring (front - body, 2e6 N/m), 20 ms. Independent truths used below:

- the critical step of a free node is ``0.99 * 2 / sqrt(2 K / m)`` with ``K`` the sum of the stiffnesses
  of its springs (the nodal bound of docs/solver.md; a crush spring counts with its unloading stiffness,
  the steepest slope);
- a consistent unit system does not change the arithmetic: the same numbers declared ``mm-ms-kg-kN``
  give the same accelerations, and standard gravity in mm/ms^2 is 9.80665e-3, so the peak in g is
  exactly 1000 times the SI one;
- a variant of a study equals the model run alone with the same parameters (to round-off, 1e-12).
"""

from __future__ import annotations

import copy
import hashlib
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import crashstudy
from crashstudy.analysis.compare import compare
from crashstudy.cli.main import _parser, main
from crashstudy.errors import InputError
from models import TWO_SPRING_CRUSH as MODEL  # noqa: E402 - the two-spring crush model of the study tests

K_FRONT = 5.0e6 + 2.0e6  # N/m: springs at the front node (crush unloading + body)
RTOL = 1e-12


def dump(path: Path, data: dict[str, Any]) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def line_of(path: Path, text: str) -> int:
    """1-based line of the first line of ``path`` that contains ``text`` (the truth for file:line)."""
    return next(i for i, ln in enumerate(path.read_text().splitlines(), 1) if text in ln)


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("newuser")
    dump(d / "model.yaml", MODEL)
    dump(
        d / "study.yaml",
        {
            "name": "speeds",
            "model": "model.yaml",
            "matrix": {"nodes.body.mass": [600.0, 800.0], "impact_velocity": [6.0, 10.0]},
        },
    )
    return d


@pytest.fixture
def study_dir(work: Path, tmp_path: Path) -> Path:
    """A fresh folder holding the 4 variants of study 'speeds'."""
    out = tmp_path / "speeds"
    crashstudy.run_study(work / "study.yaml", out)
    return out


# --------------------------------------------------------------------------------------------------
# item 1: data loss


def test_simulate_into_another_studys_folder_is_refused_and_leaves_it_unchanged(
    work: Path, study_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    before = {p.name: digest(p) for p in study_dir.iterdir() if p.is_file()}
    capsys.readouterr()
    assert main(["simulate", str(work / "model.yaml"), "-o", str(study_dir)]) == 2
    err = capsys.readouterr().err
    assert "'speeds'" in err and "--force" in err and "Traceback" not in err
    assert {p.name: digest(p) for p in study_dir.iterdir() if p.is_file()} == before
    assert len(crashstudy.open_results(study_dir).summary) == 4


def test_simulate_force_replaces_the_results_and_removes_the_plots_of_the_old_ones(
    work: Path, study_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["plot", str(study_dir)]) == 0
    old_plot = study_dir / "plots" / "history-spring_force.png"
    assert old_plot.is_file()
    mine = study_dir / "plots" / "my-notes.png"  # not written by crashstudy: never removed
    mine.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 64)
    old = crashstudy.open_results(study_dir).summary
    assert main(["simulate", str(work / "model.yaml"), "-o", str(study_dir), "--force"]) == 0
    assert not old_plot.exists() and mine.is_file()
    s = crashstudy.open_results(study_dir).summary
    assert len(s) == 1
    # the model's own parameters (800 kg, 10 m/s) are variant 3 of the study: same peak to round-off
    ref = old[(old["nodes.body.mass"] == 800.0) & (old["impact_velocity"] == 10.0)].iloc[0]
    assert s["peak_force.crush"].iloc[0] == pytest.approx(ref["peak_force.crush"], rel=RTOL)


def test_plot_into_another_results_folder_is_refused_without_force(
    work: Path, study_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    other = tmp_path / "single"
    assert main(["simulate", str(work / "model.yaml"), "-o", str(other)]) == 0
    capsys.readouterr()
    assert main(["plot", str(other), "-o", str(study_dir / "plots")]) == 2
    assert "--force" in capsys.readouterr().err
    assert not (study_dir / "plots").exists()
    assert main(["plot", str(other), "-o", str(study_dir / "plots"), "--force"]) == 0
    assert (study_dir / "plots" / "history-spring_force.png").is_file()


def test_python_simulate_still_overwrites_by_default(work: Path, study_dir: Path) -> None:
    res = crashstudy.simulate(work / "model.yaml", study_dir)
    assert len(res.summary) == 1


# --------------------------------------------------------------------------------------------------
# item 2: silent mistakes


def test_an_axis_that_changes_nothing_is_refused_by_validate_and_run(
    work: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rest = copy.deepcopy(MODEL)
    del rest["initial_velocity"]  # every node at rest: impact_velocity has nothing to rescale
    dump(tmp_path / "rest.yaml", rest)
    study = dump(
        tmp_path / "s.yaml",
        {
            "name": "at-rest",
            "model": "rest.yaml",
            "matrix": {"nodes.body.mass": [600.0, 800.0], "impact_velocity": [6.0, 10.0, 14.0]},
        },
    )
    head = f"{study}:{line_of(study, 'impact_velocity')}: matrix.impact_velocity: "
    for argv in (["validate", str(study)], ["run", str(study), "-o", str(tmp_path / "out")]):
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert any(
            ln.startswith(head) and "changes nothing" in ln and "initial_velocity" in ln
            for ln in err.splitlines()
        ), err
    assert not (tmp_path / "out").exists()  # run refused before anything was written


def test_fixed_dt_above_some_variants_critical_step_names_dt_crit_and_the_axis_values(
    work: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    masses = [0.1, 0.2, 50.0]
    study = dump(
        tmp_path / "dt.yaml",
        {
            "name": "fixed-dt",
            "model": str(work / "model.yaml"),
            "matrix": {"nodes.front.mass": masses, "impact_velocity": [6.0, 10.0]},
            "set": {"time_step": {"dt": 3.0e-4}},
        },
    )
    crit = [0.99 * 2.0 / np.sqrt(2.0 * K_FRONT / m) for m in masses]  # 1.67e-4, 2.37e-4, 2.65e-3 s
    assert crit[0] < crit[1] < 3.0e-4 < crit[2]
    head = f"{study}:{line_of(study, 'time_step')}: time_step.dt: "

    def said(err: str) -> str:
        hit = [ln for ln in err.splitlines() if head in ln]
        assert hit, err
        m = re.search(r"dt_crit=([0-9.eE+-]+)", hit[0])
        assert m and float(m.group(1)) == pytest.approx(crit[0], rel=1e-5)  # printed to 6 digits
        assert "4 of 6 variant" in hit[0] and "nodes.front.mass in [0.1, 0.2]" in hit[0]
        return hit[0]

    # some variants can run: validate warns (exit 0); run warns before it starts, fails exactly those
    capsys.readouterr()
    assert main(["validate", str(study)]) == 0
    assert said(capsys.readouterr().err).startswith("warning: ")
    assert main(["run", str(study), "-o", str(tmp_path / "out")]) == 1
    said(capsys.readouterr().err)
    s = crashstudy.open_results(tmp_path / "out").summary
    assert (s["status"] == "failed").tolist() == [m < 1.0 for m in s["nodes.front.mass"]]
    # no variant can: a mistake validate sees, reported before anything runs (exit 2, nothing written)
    none = dump(
        tmp_path / "dt-none.yaml",
        {
            "name": "fixed-dt-none",
            "model": str(work / "model.yaml"),
            "matrix": {"nodes.front.mass": masses[:2]},
            "set": {"time_step": {"dt": 3.0e-4}},
        },
    )
    for argv in (["validate", str(none)], ["run", str(none), "-o", str(tmp_path / "out2")]):
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "is above the critical step of 2 of 2 variant(s)" in err and "warning" not in err, err
    assert not (tmp_path / "out2").exists()


def test_a_study_without_model_key_is_told_so_not_read_as_a_model(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    study = dump(
        tmp_path / "s.yaml",
        {
            "name": "no-model",
            "matrix": {"nodes.body.mass": [600.0, 800.0]},
            "zip": [{"impact_velocity": [6.0, 10.0]}],
        },
    )
    assert main(["validate", str(study)]) == 2
    err = capsys.readouterr().err
    assert f"{study}:1: model: missing required field 'model'" in err
    assert "zip" not in err and "unknown key" not in err


def test_run_on_a_model_and_simulate_on_a_study_name_the_command_that_fits(
    work: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capsys.readouterr()
    assert main(["run", str(work / "model.yaml"), "-o", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "is a model, not a study" in err and f"crashstudy simulate {work / 'model.yaml'}" in err
    assert "unknown key" not in err and len(err.splitlines()) == 2
    assert main(["simulate", str(work / "study.yaml"), "-o", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "is a study, not a model" in err and f"crashstudy run {work / 'study.yaml'}" in err
    assert "missing required field" not in err and len(err.splitlines()) == 2
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_si_numbers_declared_mm_ms_kg_kn_warn_but_stay_valid(
    work: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    wrong = copy.deepcopy(MODEL)
    wrong["units"] = "mm-ms-kg-kN"  # the numbers are SI: end_time 0.02 would be 20 microseconds
    path = dump(tmp_path / "wrong.yaml", wrong)
    capsys.readouterr()
    assert main(["validate", str(path)]) == 0
    out, err = capsys.readouterr()
    assert "valid model" in out
    assert err.startswith("warning: ") and "end_time 0.02 ms" in err and "units: mm-ms-kg-kN" in err
    assert main(["simulate", str(path), "-o", str(tmp_path / "wrong")]) == 0
    err = capsys.readouterr().err
    si = crashstudy.simulate(work / "model.yaml", tmp_path / "si").summary.iloc[0]
    mm = crashstudy.open_results(tmp_path / "wrong").summary.iloc[0]
    # same arithmetic, g 1000 times smaller: the peak in g is 1000 times the SI one
    for node in ("front", "body"):
        col = f"peak_deceleration_g.{node}"
        assert mm[col] == pytest.approx(1000.0 * si[col], rel=1e-9)
    # the body (800 kg, the heaviest free mass) peaks at 10.9 g in SI: 10,857 g as mm-ms-kg-kN
    assert 1000.0 < mm["peak_deceleration_g.body"] < 1.0e5
    g_lines = [ln for ln in err.splitlines() if ln.startswith("warning: peak deceleration")]
    assert g_lines and f"{mm['peak_deceleration_g.body']:,.0f} g of node 'body'" in g_lines[0]
    # the correct SI model: no warning at all
    assert main(["validate", str(work / "model.yaml")]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("name", ["frontal-9mass", "general-nonlinear-tension", "helicopter-subfloor"])
def test_the_example_models_raise_no_plausibility_warning(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Light nodes between stiff springs (the frontal bumper, 15 kg: ~2,600 g) and prescribed motion
    (kinematic spikes) peak far above 1000 g legitimately: only the heaviest free mass is judged."""
    model = Path(__file__).resolve().parents[1] / "studies" / "models" / f"{name}.yaml"
    capsys.readouterr()
    assert main(["validate", str(model)]) == 0
    assert main(["simulate", str(model), "-o", str(tmp_path / name)]) == 0
    assert "warning" not in capsys.readouterr().err
    s = crashstudy.open_results(tmp_path / name).summary
    if name == "frontal-9mass":
        assert (
            s["peak_deceleration_g.bumper"].iloc[0] > 1000.0 > s["peak_deceleration_g.survival_room"].iloc[0]
        )


# --------------------------------------------------------------------------------------------------
# item 5: the summary table


@pytest.fixture(scope="module")
def failing_run(work: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """6 variants, 4 of them failed (fixed dt above their critical step), run through the Python API."""
    out = tmp_path_factory.mktemp("failing") / "run"
    crashstudy.run_study(
        {
            "name": "fixed-dt",
            "model": str(work / "model.yaml"),
            "matrix": {"nodes.front.mass": [0.1, 0.2, 50.0], "impact_velocity": [6.0, 10.0]},
            "set": {"time_step": {"dt": 3.0e-4}},
        },
        out,
    )
    return out


def test_summary_fits_the_terminal_width_and_prints_failure_reasons_whole(
    failing_run: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("COLUMNS", "80")
    s = crashstudy.open_results(failing_run).summary
    capsys.readouterr()
    assert main(["summary", str(failing_run), "--head", "0"]) == 0
    out = capsys.readouterr().out
    assert max(len(ln) for ln in out.splitlines()) <= 80
    assert "..." not in out  # no column hidden, no text cut
    flat = " ".join(out.split())
    reasons = [r for r in s["failure_reason"] if r]
    assert len(reasons) == 4 and all(len(r) > 80 for r in reasons)
    for v, r in zip(s["variant"], s["failure_reason"], strict=True):
        if r:
            assert f"variant {v}: {' '.join(r.split())}" in flat
    for col in s.columns:  # every column is in the (wrapped) table
        assert col == "failure_reason" or col in out


def test_summary_columns_keep_the_axes_and_sort_matches_a_unique_part(
    failing_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    s = crashstudy.open_results(failing_run).summary
    capsys.readouterr()
    assert main(["summary", str(failing_run), "--columns", "dt_crit", "--sort", "crit", "--ascending"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["variant", "nodes.front.mass", "impact_velocity", "dt_crit"]
    rows = [ln.split() for ln in lines[2:] if ln.split() and ln.split()[0].isdigit()]
    assert [int(r[1]) for r in rows] == s.sort_values("dt_crit", kind="stable")["variant"].tolist()
    # an ambiguous part is an error naming the candidates
    assert main(["summary", str(failing_run), "--sort", "peak_force"]) == 2
    err = capsys.readouterr().err
    assert "ambiguous" in err and "peak_force.crush" in err and "peak_force.body" in err


def test_summary_header_shows_the_units_stored_in_results_nc(
    failing_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    ds = crashstudy.open_results(failing_run).dataset
    assert ds["peak_force"].attrs["units"] == "N" and ds["nodes.front.mass"].attrs["units"] == "kg"
    capsys.readouterr()
    assert main(["summary", str(failing_run), "--columns", "peak_force.crush", "dt_crit"]) == 0
    lines = capsys.readouterr().out.splitlines()
    names, units = lines[0].split(), lines[1].split()
    assert names == ["variant", "nodes.front.mass", "impact_velocity", "peak_force.crush", "dt_crit"]
    assert units == ["[kg]", "[m/s]", "[N]", "[s]"]


def test_summary_variant_prints_every_column_of_that_row(
    failing_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    s = crashstudy.open_results(failing_run).summary
    capsys.readouterr()
    assert main(["summary", str(failing_run), "--variant", "4"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == len(s.columns)
    got = {ln.split()[0]: ln.split(maxsplit=1)[1] if len(ln.split()) > 1 else "" for ln in lines}
    row = s[s["variant"] == 4].iloc[0]
    assert row["nodes.front.mass"] == 50.0 and row["status"] == "ok"
    assert float(got["peak_force.crush"].split()[-1]) == pytest.approx(row["peak_force.crush"], rel=1e-5)
    assert got["dt_control"].split()[-3:] == row["dt_control"].split()[-3:]
    assert main(["summary", str(failing_run), "--variant", "6"]) == 2
    assert "0 to 5" in capsys.readouterr().err


def test_summary_head_minus_one_is_an_error(failing_run: Path, capsys: pytest.CaptureFixture[str]) -> None:
    capsys.readouterr()
    assert main(["summary", str(failing_run), "--head", "-1"]) == 2
    err = capsys.readouterr().err
    assert "--head" in err and "-1" in err and "Traceback" not in err


# --------------------------------------------------------------------------------------------------
# item 7: help texts and messages


def test_help_describes_every_argument_of_every_command() -> None:
    import argparse

    sub = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    missing = [
        f"{name} {act.dest}"
        for name, p in sub.choices.items()
        for act in p._actions
        if not isinstance(act, argparse._HelpAction) and not act.help
    ]
    assert missing == []


def test_errors_of_a_study_given_as_a_dict_name_the_dict_not_a_file_line(work: Path) -> None:
    with pytest.raises(InputError) as exc:
        crashstudy.run_study(
            {"name": "d", "model": str(work / "model.yaml"), "matrix": {"nodes.body.mas": [600.0, 800.0]}},
            work / "never",
        )
    text = str(exc.value)
    assert text.startswith("study (dict): matrix.nodes.body.mas: unknown axis"), text
    assert "<study dict>" not in text and not re.search(r":\d+:", text)


def test_compare_of_a_single_run_with_a_study_says_why_nothing_matches(
    work: Path, study_dir: Path, tmp_path: Path
) -> None:
    single = crashstudy.simulate(work / "model.yaml", tmp_path / "single")
    for new, base in ((single, study_dir), (study_dir, single)):
        cmp = compare(new, base)
        assert len(cmp.matched) == 0 and cmp.failed > 0
        assert "single model run" in cmp.report() and "no variant can be matched" in cmp.report()


def test_a_crush_curve_with_positive_forces_in_compression_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Found by a new user trying the docs: a crush curve drawn with positive forces (x < 0, y > 0) was
    valid, the spring carried min(0, curve) = 0 and the car went through the barrier with status ok."""
    bad = copy.deepcopy(MODEL)
    bad["curves"]["crush-loading"]["y"] = [60000.0, 40000.0, 0.0]
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(bad, sort_keys=False))
    capsys.readouterr()
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "springs.crush.material.loading" in err and "no negative force in compression" in err, err


def test_an_axis_that_matters_only_for_some_values_of_another_is_not_refused(
    work: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Found by the property tests on a clean clone: the body's initial speed [0, 1] crossed with
    impact_velocity [0, 1, 0] matters where impact_velocity is 1 (a node at rest gets no speed, one
    moving does), but the check tried the other axis at its first and last value only (both 0) and
    refused the axis as doing nothing. Every occurring setting of the other axes is tried now."""
    study = dump(
        tmp_path / "s.yaml",
        {
            "name": "speeds",
            "model": str(work / "model.yaml"),
            "matrix": {"initial_velocity.body.0": [0.0, -1.0], "impact_velocity": [0.0, 1.0, 0.0]},
        },
    )
    capsys.readouterr()
    assert main(["validate", str(study)]) == 0, capsys.readouterr().err


def test_output_piped_into_a_reader_that_stops_early_exits_0_without_an_error() -> None:
    """`crashstudy schema model | head -c 10`: the reader closes the pipe before the 28 kB schema is written
    (here: before the command even starts writing). That is no error of ours: exit 0 and nothing on stderr
    (it printed "error: cannot write results: [Errno 32] Broken pipe" and a second BrokenPipeError at exit)."""
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-m", "crashstudy.cli", "schema", "model"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert proc.stdout is not None
    proc.stdout.close()  # the reader is gone before the first byte
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and err == b"", (proc.returncode, err)
