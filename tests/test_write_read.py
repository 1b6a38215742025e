"""One output-folder policy and one safe writer for every command that writes; one checked reader for
every command that reads a result folder (issue 24 items 2, 3, 5, 10 (lock), issue 23 item 11).

Every command runs on one tiny model: a mass m on a spring k = 100 N/m from rest length at v0 = 1 m/s,
whose spring force is v0 sqrt(k m) sin(t sqrt(k / m)) (the closed form the numbers are checked against).
"""

from __future__ import annotations

import ast
import os
import shutil
import stat
import struct
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from crashstudy.cli.main import COMMANDS, main
from folders import MASSES, files, peak_force, snapshot

SRC = Path(__file__).resolve().parents[1] / "src" / "crashstudy"


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The inputs, and finished folders: R (precious, with sensitivity files and plots), B (other study)."""
    tmp = tmp_path_factory.mktemp("wr")
    f = files(tmp)
    assert main(["run", str(f["study"]), "-o", str(tmp / "R")]) == 0
    assert main(["run", str(f["other"]), "-o", str(tmp / "B")]) == 0
    assert main(["sensitivity", str(tmp / "R"), "--metric", "peak_force", "--history", "spring_force"]) == 0
    assert main(["plot", str(tmp / "R"), "--kind", "matrix", "--quantity", "peak_force.s"]) == 0
    return {**f, "R": tmp / "R", "B": tmp / "B", "tmp": tmp}


def copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst, symlinks=True)
    return dst


# --- item 2: optimize/calibrate onto another study's results ---------------------------------------


@pytest.mark.parametrize("command", ["optimize", "calibrate"])
def test_optimize_and_calibrate_refuse_another_studys_results_unless_forced(
    made: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    study = made["opt" if command == "optimize" else "cal"]
    out = copy(made["R"], tmp_path / "R")
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    capsys.readouterr()
    assert main([command, str(study), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "holds the results of 'precious'" in err and "--force" in err and "Traceback" not in err, err
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before  # nothing touched
    assert main([command, str(study), "-o", str(out), "--force"]) in (0, 1)
    s = pd.read_parquet(out / "summary.parquet")
    assert len(s) == 1 and s["peak_force.s"].iloc[0] == pytest.approx(
        peak_force(s["nodes.b.mass"].iloc[0]), rel=2e-3
    )


# --- item 3: every file every command writes, a planted link at its name ----------------------------


WRITERS = {
    "run",
    "simulate",
    "optimize",
    "calibrate",
    "sensitivity",
    "plot",
    "compare",
    "report",
    "export",
    "import",
    "correlate",
}
READERS = {"summary", "plot", "compare", "sensitivity", "report", "export", "correlate"}  # of a result folder
NEITHER = {"validate", "schema"}


def test_every_command_is_known_as_a_writer_a_reader_or_neither() -> None:
    """A new command fails here until it is added to the link test (writer) and the tamper test (reader)."""
    from crashstudy.cli.main import _parser

    _parser()  # the plugged command families register while the parser is built
    assert set(COMMANDS) == WRITERS | READERS | NEITHER


def _argv(made: dict[str, Path], command: str, tmp: Path) -> tuple[list[str], Path]:
    """(command line, the folder it writes into) for each writing command."""
    if command in ("sensitivity", "plot", "compare", "report", "correlate"):
        r = copy(made["R"], tmp / "R")
        return {
            "sensitivity": ["sensitivity", str(r), "--metric", "peak_force", "--history", "spring_force"],
            "report": ["report", str(r)],
            "correlate": [
                "correlate",
                str(r),
                "--test",
                str(made["tmp"] / "data.csv"),
                "--item",
                "s",
                "--quantity",
                "force",
            ],
            "plot": ["plot", str(r), "--kind", "history"],
            "compare": ["compare", str(r), str(made["R"]), "--junit", str(r / "junit.xml")],
        }[command], r
    if (
        command == "export"
    ):  # the ISO-MME side reads a result folder (the LS-DYNA side: tests/test_dyna_exchange_*.py)
        return ["export", str(made["R"]), "--isomme", str(tmp / "ISO")], tmp / "ISO"
    if command == "import":
        (tmp / "M").mkdir()
        assert main(["export", str(made["model"]), "--dyna", str(tmp / "model.k")]) == 0
        return ["import", str(tmp / "model.k"), "-o", str(tmp / "M" / "model.yaml")], tmp / "M"
    study = {
        "run": made["study"],
        "simulate": made["model"],
        "optimize": made["opt"],
        "calibrate": made["cal"],
    }[command]
    return [command, str(study), "-o", str(tmp / "O")], tmp / "O"


@pytest.mark.parametrize("command", sorted(WRITERS))
def test_a_link_planted_at_every_file_a_command_writes_is_replaced_never_followed(
    made: dict[str, Path], tmp_path: Path, command: str
) -> None:
    """The command runs once; every file it wrote or changed is then replaced by a link to a file outside,
    and it runs again (with --force where it has one: a link at results.nc is otherwise refused, which
    is safe too). The outside files keep their bytes, and every name is a regular file again."""
    argv, folder = _argv(made, command, tmp_path)
    before = snapshot(folder) if folder.exists() else {}
    assert main(argv) in (0, 1)
    after = snapshot(folder)
    written = sorted(n for n, s in after.items() if before.get(n) != s)
    assert written, "the command wrote nothing"
    outside = tmp_path / "outside"
    outside.mkdir()
    for k, name in enumerate(written):
        target = outside / f"victim{k}"
        target.write_text(f"precious {k}\n")
        (folder / name).unlink()
        (folder / name).symlink_to(target)
    forced = ("run", "simulate", "optimize", "calibrate", "report", "export", "import")
    again = argv + (["--force"] if command in forced else [])
    assert main(again) in (0, 1)
    for k, name in enumerate(written):
        assert (outside / f"victim{k}").read_text() == f"precious {k}\n", name
        assert stat.S_ISREG(os.lstat(folder / name).st_mode), f"{name} is not a regular file after {command}"
    assert not [n for n in snapshot(folder) if n.endswith(".partial")]


def test_a_set_of_files_is_replaced_whole_or_not_at_all(tmp_path: Path) -> None:
    """write_all stages every file before renaming any: a failure while the second is written leaves
    both earlier files as they were (a killed optimize re-run cannot leave an empty history.csv beside
    the old optimum.yaml)."""
    from crashstudy.safefs import write_all

    a, b = tmp_path / "history.csv", tmp_path / "optimum.yaml"
    a.write_text("old history\n")
    b.write_text("old optimum\n")

    def boom(fh: object) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_all([(a, lambda fh: fh.write(b"new history\n")), (b, boom)])
    assert a.read_text() == "old history\n" and b.read_text() == "old optimum\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["history.csv", "optimum.yaml"]
    write_all([(a, lambda fh: fh.write(b"new history\n")), (b, lambda fh: fh.write(b"new optimum\n"))])
    assert a.read_text() == "new history\n" and b.read_text() == "new optimum\n"


# --- issue 23 item 11: everything derived from a result goes with it --------------------------------


def test_run_force_removes_every_file_derived_from_the_old_results_and_keeps_the_users(
    made: dict[str, Path], tmp_path: Path
) -> None:
    out = copy(made["R"], tmp_path / "R")
    derived = ["sensitivity.csv", "sensitivity_spring_force.nc", "sensitivity_spring_force.png"]
    assert all((out / n).is_file() for n in derived) and list((out / "plots").glob("*.png"))
    (out / "notes.txt").write_text("my notes\n")
    assert main(["run", str(made["study"]), "-o", str(out), "--force"]) == 0
    assert [n for n in derived if os.path.lexists(out / n)] == []
    assert not (out / "plots").exists()
    assert (out / "notes.txt").read_text() == "my notes\n"
    s = pd.read_parquet(out / "summary.parquet")
    np.testing.assert_allclose(s["peak_force.s"], [peak_force(m) for m in MASSES], rtol=2e-3)


# --- item 10 (part): a FIFO at the lock's name --------------------------------------------------------


def test_a_fifo_planted_as_the_lock_file_is_named(
    made: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "O"
    out.mkdir()
    os.mkfifo(out / ".crashstudy.lock")
    capsys.readouterr()
    assert main(["run", str(made["study"]), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert ".crashstudy.lock" in err and "regular file" in err and "Errno" not in err, err


# --- item 5: tampered results are refused by every reader ------------------------------------------


def _tampered(made: dict[str, Path], tmp: Path, how: str) -> Path:
    t = copy(made["R"], tmp / how)
    if how == "edited":  # one stored number doubled in place: same size, so only the SHA-256 tells
        raw = (t / "summary.parquet").read_bytes()
        old = struct.pack("<d", pd.read_parquet(t / "summary.parquet")["peak_force.s"].iloc[1])
        assert raw.count(old) == 1
        (t / "summary.parquet").write_bytes(
            raw.replace(old, struct.pack("<d", 2.0 * struct.unpack("<d", old)[0]))
        )
        assert pd.read_parquet(t / "summary.parquet")["peak_force.s"].iloc[1] == pytest.approx(
            2 * peak_force(2.0), rel=2e-3
        )
    elif how == "beside-another":  # this study's summaries beside the other study's results.nc + manifest
        for name in ("results.nc", "manifest.json"):
            shutil.copy(made["B"] / name, t / name)
    return t


READS = {
    "summary": ["summary", "{d}"],
    "exceed": ["summary", "{d}", "--exceed", "peak_force.s", "1"],
    "sensitivity": ["sensitivity", "{d}", "--metric", "peak_force"],
    "plot": ["plot", "{d}", "--kind", "matrix", "--quantity", "peak_force.s", "-o", "{d}/../plots-{h}"],
    "compare": ["compare", "{d}", "{r}"],
    "report": ["report", "{d}", "-o", "{d}/../report-{h}.html"],
    "export": ["export", "{d}", "--isomme", "{d}/../iso-{h}"],
}
# correlate reads no summary, only results.nc: test_correlate_refuses_a_results_file_the_manifest_does_not_vouch_for


@pytest.mark.parametrize("how", ["edited", "beside-another"])
@pytest.mark.parametrize("command", sorted(READS))
def test_every_reader_refuses_summaries_the_manifest_does_not_vouch_for(
    made: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str, how: str
) -> None:
    t = _tampered(made, tmp_path, how)
    kept = (t / "sensitivity.csv").read_bytes()
    capsys.readouterr()
    argv = [a.format(d=t, r=made["R"], h=how) for a in READS[command]]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "manifest.json" in err and "Traceback" not in err, err
    assert (t / "sensitivity.csv").read_bytes() == kept  # nothing written from refused results


def test_correlate_refuses_a_results_file_the_manifest_does_not_vouch_for(
    made: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    t = copy(made["R"], tmp_path / "grown")
    with open(t / "results.nc", "ab") as fh:
        fh.write(b"\0")
    capsys.readouterr()
    assert (
        main(
            [
                "correlate",
                str(t),
                "--test",
                str(made["tmp"] / "data.csv"),
                "--item",
                "s",
                "--quantity",
                "force",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "manifest.json" in err and "Traceback" not in err, err
    assert not (t / "correlation.csv").exists()


def test_open_results_refuses_an_edited_summary(made: dict[str, Path], tmp_path: Path) -> None:
    from crashstudy import open_results
    from crashstudy.errors import InputError

    res = open_results(made["R"])
    np.testing.assert_allclose(res.summary["peak_force.s"], [peak_force(m) for m in MASSES], rtol=2e-3)
    res.close()
    res = open_results(_tampered(made, tmp_path, "edited"))
    with pytest.raises(InputError, match="SHA-256 of summary.parquet"):
        _ = res.summary


# --- the static rule: no module writes or reads a result file except through the one writer/reader ---

WRITE_CALLS = {
    "to_csv",
    "to_parquet",
    "to_netcdf",
    "savefig",
    "write_text",
    "write_bytes",
    "replace",
    "rename",
    "ParquetWriter",
    "CSVWriter",
    "mkfifo",
    "symlink_to",
    "copyfile",
    "copy",
    "move",
}
READ_CALLS = {
    "read_parquet",
    "read_csv",
    "open_dataset",
    "open_mfdataset",
    "load_dataset",
    "Dataset",
    "read_table",
}
SAFE_OPENERS = {"replacing", "replacing_path", "open_new", "open_regular", "open_file"}
# the writes and reads that do not go through safefs / results.reader, each with its reason
ALLOWED = {
    ("results/store.py", "Dataset"): 3,  # the run's own results.nc.partial (created by safefs.create_new)
    (
        "results/store.py",
        "replace",
    ): 2,  # the partial store and the summaries renamed into place (checked names)
    # a Zarr folder replacing a folder: staged, then swapped in one step (or, without renameat2, moved aside)
    ("results/placement.py", "replace"): 3,
    ("results/tables.py", "ParquetWriter"): 1,  # into a handle from safefs.open_new
    (
        "results/summary_stream.py",
        "ParquetWriter",
    ): 1,  # into a handle from safefs.open_new, open across the chunks
    ("results/tables.py", "CSVWriter"): 1,  # into a handle from safefs.open_new
    (
        "results/summary_stream.py",
        "CSVWriter",
    ): 1,  # into a handle from safefs.open_new, beside the Parquet one
    ("results/reader.py", "Dataset"): 1,  # the reader itself (Results.stored), after safefs.open_regular
    ("results/tables.py", "replace"): 1,  # the staged summaries renamed into place
    ("results/integrity.py", "Dataset"): 1,  # results.nc, after safefs.open_regular checked it
    ("results/outdir.py", "Dataset"): 1,  # results.nc, after safefs.open_regular checked it
    ("run/runner.py", "Dataset"): 1,  # an earlier results.nc for reuse: each variant's checksum is verified
    ("kernel/generated.py", "write_text"): 1,  # kernel source in the private, owner-checked kernel folder
    ("kernel/generated.py", "replace"): 1,  # ditto
    ("kernel/choice.py", "open-for-writing"): 1,  # a lock file in the private, owner-checked kernel folder
    ("kernel/warm.py", "open-for-writing"): 1,  # ditto
    (
        "kernel/compile_lock.py",
        "open-for-writing",
    ): 1,  # ditto (the compile lock and what its holder compiles)
    ("exchange/testcurve.py", "read_csv"): 1,  # a CSV test curve from bytes read by safefs.open_regular
    (
        "analysis/report_extra.py",
        "read_csv",
    ): 1,  # sensitivity/correlation/history.csv from safefs.open_regular bytes
    # scratch files of a large compare / correlation (hash parts, rank buckets) in a fresh private
    # tempfile.TemporaryDirectory (mode 0700, unpredictable name, removed when the command ends): not results
    ("analysis/compare_match.py", "open-for-writing"): 1,
    ("analysis/correlation.py", "open-for-writing"): 1,
    ("results/reader.py", "open_dataset"): 3,  # the reader itself: results.nc, results.zarr, the raw store
    ("results/reader.py", "read_parquet"): 2,  # the reader itself, from a manifest-checked handle
    ("results/reader.py", "read_csv"): 1,  # the reader itself, from a manifest-checked handle
}


def _calls(tree: ast.AST) -> list[tuple[str, ast.Call]]:
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
            out.append((name, node))
    return out


def _safe_names(tree: ast.AST) -> set[str]:
    """Names bound to handles of the one writer/reader: ``with replacing(...) as fh``, and the parameter
    of a ``lambda fh: ...`` (write_all's fill functions)."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.With):
            for item in node.items:
                c = item.context_expr
                fn = c.func if isinstance(c, ast.Call) else None
                called = (
                    fn.attr if isinstance(fn, ast.Attribute) else fn.id if isinstance(fn, ast.Name) else ""
                )
                if called in SAFE_OPENERS and isinstance(item.optional_vars, ast.Name):
                    names.add(item.optional_vars.id)
        elif isinstance(node, ast.Lambda):
            names.update(a.arg for a in node.args.args)
    return names


def test_no_module_writes_or_reads_files_around_the_one_writer_and_reader() -> None:
    """Outside safefs.py, a call that writes a file (to_csv(path), savefig(path), to_netcdf, write_text,
    os.replace, open(..., 'w'), ...) or reads a result file (read_parquet, open_dataset, netCDF4.Dataset)
    is allowed only into a handle of the one writer/reader, or where ALLOWED says why. A new command
    that writes or reads around them fails here."""
    found: dict[tuple[str, str], int] = {}
    for path in sorted(SRC.rglob("*.py")):
        rel = str(path.relative_to(SRC))
        if rel == "safefs.py":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        safe = _safe_names(tree)
        writer = {
            a.asname or a.name
            for n in ast.walk(tree)
            if isinstance(n, ast.ImportFrom) and n.module == "crashstudy.safefs"
            for a in n.names
        }
        for name, call in _calls(tree):
            first = call.args[0] if call.args else None
            if name == "open" and isinstance(call.func, ast.Name):
                mode = (
                    call.args[1]
                    if len(call.args) > 1
                    else next((k.value for k in call.keywords if k.arg == "mode"), None)
                )
                text = mode.value if isinstance(mode, ast.Constant) and isinstance(mode.value, str) else "r"
                if any(c in text for c in "wax+"):
                    found[(rel, "open-for-writing")] = found.get((rel, "open-for-writing"), 0) + 1
                continue
            if name not in WRITE_CALLS | READ_CALLS or (isinstance(first, ast.Name) and first.id in safe):
                continue
            if isinstance(call.func, ast.Name) and name in writer:
                continue  # the one writer's own functions (safefs.write_text, ...)
            if name == "Dataset" and not (
                isinstance(call.func, ast.Name)
                or (
                    isinstance(call.func, ast.Attribute)
                    and isinstance(call.func.value, ast.Name)
                    and call.func.value.id == "netCDF4"
                )
            ):
                continue  # xr.Dataset(...): built in memory
            if (
                name in ("to_csv", "to_parquet")
                and first is None
                and not any(k.arg in ("path_or_buf", "path") for k in call.keywords)
            ):
                continue  # returns the text: written by the caller through the one writer
            if name in ("replace", "copy", "move", "rename") and not _is_os_call(call):
                continue  # str.replace, dict.copy, DataFrame.rename, ...
            found[(rel, name)] = found.get((rel, name), 0) + 1
    unexpected = {k: v for k, v in found.items() if v > ALLOWED.get(k, 0)}
    assert not unexpected, f"writes/reads around crashstudy.safefs / results.reader: {unexpected}"


def _is_os_call(call: ast.Call) -> bool:
    f = call.func
    return (
        isinstance(f, ast.Attribute)
        and isinstance(f.value, ast.Name)
        and f.value.id in ("os", "shutil", "Path")
    )
