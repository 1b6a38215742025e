"""Studies end to end (docs/studies.md, issue 3): interruption, resume and overwrite: an interrupted
run resumed gives files bit-identical to an uninterrupted run (every variable, NaN where NaN, every
attribute); a changed study is not resumed, finished results are not overwritten without ``--force``.

The test model is a 1-D frontal impact: a crush spring (wall - front mass) and a linear body spring
(front - body), 20 ms at 5 kHz sampling, a few hundred steps: every run here takes milliseconds
(models.TWO_SPRING_CRUSH). What these tests share is in study_cases.py."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from crashstudy.cli.main import main
from crashstudy.run.runner import run_plan
from crashstudy.study.plan import load_study
from study_cases import dump, load_ds


def assert_identical(a: xr.Dataset, b: xr.Dataset) -> None:
    """Bit-identical results: same variables, values (NaN where NaN), and attributes."""
    assert sorted(a.variables) == sorted(b.variables)
    for name in a.variables:
        va, vb = a[name].values, b[name].values
        if va.dtype.kind in "OSU":
            assert (va == vb).all(), name
        else:
            np.testing.assert_array_equal(va, vb, err_msg=name)
        assert _attrs(a[name].attrs) == _attrs(b[name].attrs), name
    assert a.attrs == b.attrs


def _attrs(attrs: dict) -> dict:
    """Attributes with arrays (CF flag_values) as lists, so that dicts compare."""
    return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in attrs.items()}


# --------------------------------------------------------------------------------------------------
# backends, interruption, resume, overwrite


# --jobs 2 against the in-process run (bitwise, small chunks, every history; interrupted and resumed too):
# tests/test_backends.py::TestProcessPool


# A CLI run slowed down to ~0.25 s per chunk of 5 variants, so that a signal lands mid-run: the real
# command line (crashstudy.cli.main), with the chunk size and a delay patched in before it starts.
SLOW_CLI = """\
import sys, time
import crashstudy.run.runner as runner
runner.MAX_CHUNK = 5
_run_chunk = runner.run_chunk
def slow_chunk(*args, **kw):
    time.sleep(0.25)
    return _run_chunk(*args, **kw)
runner.run_chunk = slow_chunk
from crashstudy.cli.main import main
sys.exit(main(sys.argv[1:]))
"""

# Reads the `done` flags of a partial file while the run still has it open for writing (HDF5 file
# locking must be off for that, and it is read when the library starts: hence its own process).
DONE_READER = """\
import sys
import netCDF4, numpy as np
for line in sys.stdin:
    try:
        with netCDF4.Dataset(line.strip()) as nc:
            print(int(np.asarray(nc.variables["done"][:]).sum()), flush=True)
    except Exception:
        print(-1, flush=True)
"""


@pytest.fixture(scope="module")
def resume_study(work: Path) -> tuple[Path, Path]:
    """A 120-variant study and its uninterrupted, in-process result."""
    study = dump(
        work / "resume.yaml",
        {
            "name": "resume-check",
            "model": "model.yaml",
            "matrix": {
                "nodes.body.mass": [float(m) for m in np.linspace(600, 1000, 6)],
                "impact_velocity": [float(v) for v in np.linspace(4, 12, 20)],
            },
        },
    )
    ref = work / "resume-ref"
    run_plan(load_study(study), ref, progress=False)
    return study, ref


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGKILL], ids=["ctrl-c", "killed"])
def test_interrupted_run_resumes_to_results_identical_to_an_uninterrupted_run(
    sig: signal.Signals, resume_study: tuple[Path, Path], work: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    study, ref = resume_study
    out = work / f"resume-{sig.name}"
    partial, final = out / "results.nc.partial", out / "results.nc"
    reader = subprocess.Popen(
        [sys.executable, "-c", DONE_READER],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "HDF5_USE_FILE_LOCKING": "FALSE"},
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", SLOW_CLI, "run", str(study), "-o", str(out), "--progress", "off"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # (as in a terminal)
    try:
        done, deadline = 0, time.monotonic() + 120
        while done < 10:  # two chunks written and flushed (24 chunks in all: > 5 s to go)
            assert proc.poll() is None, f"the run ended before it could be interrupted: {proc.communicate()}"
            assert time.monotonic() < deadline, "no variant finished within 120 s"
            assert not final.exists(), "results.nc exists while the run is still going"
            if partial.exists():
                assert reader.stdin and reader.stdout
                reader.stdin.write(f"{partial}\n")
                reader.stdin.flush()
                done = int(reader.stdout.readline())
            time.sleep(0.05)
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
        reader.kill()
        reader.wait()
    if sig == signal.SIGINT:
        assert proc.returncode == 130, (stdout, stderr)
        assert "--resume" in stderr
    else:
        assert proc.returncode == -signal.SIGKILL, (stdout, stderr)
    # nothing looks complete
    assert not final.exists() and not (out / "summary.csv").exists(), (stdout, stderr)
    assert partial.exists()
    with xr.open_dataset(partial) as ds:
        n_done = int((ds["done"].fillna(0).values > 0).sum())
    assert 10 <= n_done < 120, (n_done, stdout, stderr)

    # an unfinished run is not silently restarted or finished
    assert main(["run", str(study), "-o", str(out), "--progress", "off"]) == 2
    assert "--resume" in capsys.readouterr().err
    assert main(["run", str(study), "-o", str(out), "--resume", "--progress", "off"]) == 0
    assert f"({120 - n_done} variants computed" in capsys.readouterr().out  # only the missing ones
    assert final.exists() and not partial.exists()
    assert_identical(load_ds(out), load_ds(ref))
    pd.testing.assert_frame_equal(pd.read_csv(out / "summary.csv"), pd.read_csv(ref / "summary.csv"))


def test_resume_after_the_study_changed_is_refused_as_invalid_input(
    work: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    study = dump(
        work / "changed.yaml",
        {"name": "changed", "model": "model.yaml", "matrix": {"impact_velocity": [4.0, 6.0, 8.0]}},
    )
    out = work / "changed-out"
    import crashstudy.run.runner as runner

    calls = []
    real = runner.run_chunk

    def interrupted_after_one_chunk(*args: Any, **kw: Any) -> Any:
        calls.append(1)
        if len(calls) > 1:
            raise KeyboardInterrupt
        return real(*args, **kw)

    with monkeypatch.context() as mp:
        mp.setattr(runner, "MAX_CHUNK", 1)
        mp.setattr(runner, "run_chunk", interrupted_after_one_chunk)
        assert main(["run", str(study), "-o", str(out), "--progress", "off"]) == 130
    assert (out / "results.nc.partial").exists()
    dump(study, {"name": "changed", "model": "model.yaml", "matrix": {"impact_velocity": [4.0, 6.0, 9.0]}})
    capsys.readouterr()
    assert main(["run", str(study), "-o", str(out), "--resume", "--progress", "off"]) == 2
    err = capsys.readouterr().err
    assert "--force" in err and "Traceback" not in err


def test_finished_results_are_not_overwritten_without_force(
    resume_study: tuple[Path, Path], work: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Another study's finished results in the folder: exit 2, files untouched; ``--force`` replaces them.

    (Re-running the *same* study into its folder reuses its unchanged variants: the result stays
    identical, see test_provenance.py; checked here too.)
    """
    study, ref = resume_study
    out = work / "overwrite"
    assert main(["run", str(study), "-o", str(out), "--progress", "off"]) == 0
    before = {p.name: p.read_bytes() for p in (out / "results.nc", out / "summary.csv")}
    other = dump(
        work / "other.yaml",
        {"name": "another-study", "model": "model.yaml", "matrix": {"impact_velocity": [3.0, 5.0]}},
    )
    capsys.readouterr()
    assert main(["run", str(other), "-o", str(out), "--progress", "off"]) == 2
    err = capsys.readouterr().err
    assert "--force" in err and "resume-check" in err
    assert {p.name: p.read_bytes() for p in (out / "results.nc", out / "summary.csv")} == before
    assert not (out / "results.nc.partial").exists()

    assert main(["run", str(other), "-o", str(out), "--progress", "off", "--force"]) == 0
    ds = load_ds(out)
    assert ds.attrs["study_name"] == "another-study" and ds.sizes["variant"] == 2
    np.testing.assert_array_equal(ds["impact_velocity"].values, [3.0, 5.0])

    # the same study again, into the folder of its own finished result: everything reused, identical
    same = work / "same"
    assert main(["run", str(study), "-o", str(same), "--progress", "off"]) == 0
    assert main(["run", str(study), "-o", str(same), "--progress", "off"]) == 0
    assert "(0 variants computed" in capsys.readouterr().out
    assert_identical(load_ds(same), load_ds(ref))
