"""Faults, with real files: paths through the command line (issue 5, item 4): where a study's model is
looked up, that output is written only inside the chosen folder, and that existing results are not
overwritten without ``--force``.

The contract under test (docs/studies.md, issue 5) and the shared fault study are described in
fault_runs.py."""

from __future__ import annotations

from pathlib import Path

import pytest

from fault_runs import FAULT_MODEL, SMALL_STUDY, assert_clean_message, files_under, load
from helpers import run_cli as cli  # the command line in this process (helpers.run_cli)

# ------------------------------------------------------------------------------------------------
# paths
# ------------------------------------------------------------------------------------------------


def test_model_path_is_relative_to_the_study_file_not_the_working_directory(tmp_path: Path) -> None:
    proj = tmp_path / "project"
    (proj / "models").mkdir(parents=True)
    (proj / "models" / "fault-model.yaml").write_text(FAULT_MODEL)
    (proj / "small.yaml").write_text(SMALL_STUDY)
    elsewhere = tmp_path / "elsewhere"
    (elsewhere / "models").mkdir(parents=True)
    (elsewhere / "models" / "fault-model.yaml").write_text(
        "name: decoy\nnodes: {}\n"
    )  # invalid if it were read
    for study in ("../project/small.yaml", str(proj / "small.yaml")):
        p = cli("validate", study, cwd=elsewhere)
        assert p.returncode == 0 and "valid study (6 variants)" in p.stdout, p.stderr
    p = cli("run", "../project/small.yaml", "-o", "out", "--progress", "off", cwd=elsewhere)
    assert p.returncode == 0, p.stderr
    ds = load(elsewhere / "out")
    assert Path(ds.attrs["model_file"]).resolve() == (proj / "models" / "fault-model.yaml").resolve()
    assert ds.attrs["model_yaml"] == FAULT_MODEL


def test_output_is_written_only_inside_the_chosen_folder(fault_dir: Path, tmp_path: Path) -> None:
    proj = tmp_path / "project"
    (proj / "models").mkdir(parents=True)
    (proj / "models" / "fault-model.yaml").write_text(FAULT_MODEL)
    (proj / "small.yaml").write_text(SMALL_STUDY)
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    before = files_under(tmp_path)
    steps = [
        ("run", "../project/small.yaml", "-o", "../chosen/run", "--progress", "off"),
        ("simulate", str(proj / "models" / "fault-model.yaml"), "-o", str(tmp_path / "chosen" / "sim")),
        ("run", "../project/small.yaml", "-o", "../chosen/run", "--force", "--progress", "off"),
        ("run", "../project/small.yaml", "--dry-run"),
        ("validate", "../project/small.yaml"),
        ("summary", "../chosen/run"),
    ]
    for argv in steps:
        p = cli(*argv, cwd=cwd)
        assert p.returncode == 0, (argv, p.stderr)
    new = files_under(tmp_path) - before
    assert new and all(f == "chosen" or f.startswith("chosen/") for f in new), sorted(new)
    assert sorted(new) == [
        "chosen",
        "chosen/run",
        "chosen/run/manifest.json",
        "chosen/run/results.nc",
        "chosen/run/summary.csv",
        "chosen/run/summary.parquet",
        "chosen/sim",
        "chosen/sim/manifest.json",
        "chosen/sim/results.nc",
        "chosen/sim/summary.csv",
        "chosen/sim/summary.parquet",
    ]
    # without -o the folder is results/<study name> under the working directory, and nothing else
    p = cli("run", "../project/small.yaml", "--progress", "off", cwd=cwd)
    assert p.returncode == 0, p.stderr
    assert files_under(cwd) == {
        "results",
        "results/small-study",
        "results/small-study/results.nc",
        "results/small-study/summary.csv",
        "results/small-study/summary.parquet",
        "results/small-study/manifest.json",
    }


@pytest.mark.parametrize("name", ["../escape", "a/b", "/abs", ".."])
def test_study_name_cannot_steer_the_default_output_folder(tmp_path: Path, name: str) -> None:
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "fault-model.yaml").write_text(FAULT_MODEL)
    (tmp_path / "s.yaml").write_text(SMALL_STUDY.replace("name: small-study", f"name: '{name}'"))
    (tmp_path / "cwd").mkdir()
    before = files_under(tmp_path)
    p = cli("run", "../s.yaml", "--progress", "off", cwd=tmp_path / "cwd")
    assert p.returncode == 2, p.stderr
    assert "s.yaml:1: name:" in p.stderr
    assert files_under(tmp_path) == before


def test_existing_results_are_not_overwritten_without_force(fault_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    p = cli("run", fault_dir / "small.yaml", "-o", out, "--progress", "off")
    assert p.returncode == 0, p.stderr
    stamp = {f: ((out / f).read_bytes(), (out / f).stat().st_mtime_ns) for f in ("results.nc", "summary.csv")}
    (out / "notes.txt").write_text("mine\n")
    # another study into the same folder: refused, exit 2, nothing touched
    other = fault_dir / "other.yaml"
    other.write_text(SMALL_STUDY.replace("name: small-study", "name: other-study"))
    p = cli("run", other, "-o", out, "--progress", "off")
    assert p.returncode == 2, p.stderr
    assert_clean_message(p.stderr)
    assert "--force" in p.stderr and "other-study" in p.stderr and "small-study" in p.stderr
    for f, (data, mtime) in stamp.items():
        assert (out / f).read_bytes() == data and (out / f).stat().st_mtime_ns == mtime
    # the same study again: its finished variants are reused, the numbers stay identical
    ref = load(out)
    p = cli("run", fault_dir / "small.yaml", "-o", out, "--progress", "off")
    assert p.returncode == 0, p.stderr
    assert "(0 variants computed" in p.stdout, p.stdout
    again = load(out)
    for name in ref.variables:
        assert again[name].equals(ref[name]), name
    # --force recomputes, and removes only its own files
    p = cli("run", other, "-o", out, "--force", "--progress", "off")
    assert p.returncode == 0, p.stderr
    assert load(out).attrs["study_name"] == "other-study"
    assert (out / "notes.txt").read_text() == "mine\n"
    assert sorted(x.name for x in out.iterdir()) == [
        "manifest.json",
        "notes.txt",
        "results.nc",
        "summary.csv",
        "summary.parquet",
    ]
