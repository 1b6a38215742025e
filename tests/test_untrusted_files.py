"""Files that are not what they claim (FIFOs, links to /dev/zero or to a secret, data outside the model's
time) and stop signals, in real processes (issue 24 items 4, 5, 7, 8). A process that would hang or fill
memory before the fix is started with a time limit and an address-space limit, so that it fails the
test instead of the machine."""

from __future__ import annotations

import os
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from crashstudy.cli.main import main
from folders import files, peak_force, snapshot
from helpers import run_cli, run_cli_in_one_process


def limited() -> None:
    """In the child: Ctrl-C as in a terminal, and at most 3 GiB of address space (/dev/zero read into
    memory ends in MemoryError, not in the machine's out-of-memory killer)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, 3 * 2**30))


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    tmp = tmp_path_factory.mktemp("untrusted")
    f = files(tmp)
    assert main(["run", str(f["study"]), "-o", str(tmp / "R")]) == 0
    return {**f, "R": tmp / "R", "tmp": tmp}


# --- item 5: a FIFO or a link to /dev/zero in a result folder ---------------------------------------


PLANTED = [
    ("manifest.json", "fifo"),
    ("summary.parquet", "zero"),
    ("results.nc", "fifo"),
    ("manifest.json", "zero"),
]


def in_one_process(
    *commands: tuple[str, ...], timeout: float = 180
) -> list[subprocess.CompletedProcess[str]]:
    """The commands in one subprocess (helpers.run_cli_in_one_process) with Ctrl-C as in a terminal and
    3 GiB of address space (:func:`limited`); a hang fails the tests after ``timeout`` seconds."""
    try:
        return run_cli_in_one_process(*commands, timeout=timeout, preexec_fn=limited)
    except subprocess.TimeoutExpired:
        pytest.fail(f"one of {commands} hung for {timeout} s")


@pytest.fixture(scope="module")
def planted_summaries(
    made: dict[str, Path], tmp_path_factory: pytest.TempPathFactory
) -> dict[tuple[str, str], subprocess.CompletedProcess[str]]:
    """``crashstudy summary`` of copies of the result folder, each with one file of PLANTED replaced by a
    FIFO or a link to /dev/zero: every case in one subprocess (one interpreter start instead of four)."""
    folders = []
    for name, plant in PLANTED:
        t = shutil.copytree(made["R"], tmp_path_factory.mktemp("planted") / "R")
        (t / name).unlink()
        if plant == "fifo":
            os.mkfifo(t / name)
        else:
            (t / name).symlink_to("/dev/zero")
        folders.append(("summary", str(t)))
    return dict(zip(PLANTED, in_one_process(*folders), strict=True))


@pytest.mark.parametrize(("name", "plant"), PLANTED)
def test_summary_refuses_a_fifo_or_a_link_to_dev_zero_in_a_result_folder(
    planted_summaries: dict[tuple[str, str], subprocess.CompletedProcess[str]], name: str, plant: str
) -> None:
    done = planted_summaries[(name, plant)]
    assert done.returncode == 2, done.stderr[-2000:]
    assert name in done.stderr and "Traceback" not in done.stderr, done.stderr


# --- items 4 and 7: calibrate.data -----------------------------------------------------------------


def _with_data(made: dict[str, Path], tmp: Path, plant: str) -> Path:
    """The calibrate study beside a data.csv that is ``plant``."""
    shutil.copy(made["model"], tmp / "model.yaml")
    shutil.copy(made["cal"], tmp / "cal.yaml")
    data = tmp / "data.csv"
    if plant == "fifo":
        os.mkfifo(data)
    elif plant == "zero":
        data.symlink_to("/dev/zero")
    elif plant == "secret":
        secret = tmp / "shadow"
        secret.write_text("alice:$6$s3cr3tHash:19000:0:99999:7:::\nbob:$6$0therHash:19000:0:99999:7:::\n")
        data.symlink_to(secret)
    else:  # times past end_time (0.05 s) or before t = 0
        t = np.linspace(0.0, 0.08, 81) if plant == "late" else np.linspace(-0.01, 0.05, 61)
        pd.DataFrame({"time": t, "value": np.sqrt(200.0) * np.sin(t * np.sqrt(50.0))}).to_csv(
            data, index=False
        )
    return tmp / "cal.yaml"


@pytest.fixture(scope="module")
def calibrated_from_devices(
    made: dict[str, Path], tmp_path_factory: pytest.TempPathFactory
) -> dict[str, tuple[Path, subprocess.CompletedProcess[str]]]:
    """``crashstudy calibrate`` with data.csv a FIFO and a link to /dev/zero, whose read would hang or
    fill memory: both in one subprocess; {plant: (its folder, what the command did)}."""
    folders = {plant: tmp_path_factory.mktemp(f"calibrate-{plant}") for plant in ("fifo", "zero")}
    commands = [
        ("calibrate", str(_with_data(made, tmp, plant)), "-o", str(tmp / "out"))
        for plant, tmp in folders.items()
    ]
    return {
        plant: (tmp, p) for (plant, tmp), p in zip(folders.items(), in_one_process(*commands), strict=True)
    }


@pytest.mark.parametrize(
    ("plant", "expected"),
    [
        ("fifo", "it is a named pipe (FIFO); expected a regular file"),
        ("zero", "expected a regular file"),
        ("secret", "line 1: expected the header 'time,value'"),
        ("late", "line 53: the data run from t = 0 to 0.08, the model from 0 to end_time 0.05"),
        ("early", "line 2: the data run from t = -0.01 to 0.05"),
    ],
)
def test_calibrate_data_is_read_only_as_a_regular_file_within_the_models_time(
    made: dict[str, Path], tmp_path: Path, plant: str, expected: str, request: pytest.FixtureRequest
) -> None:
    """Never hangs, never fills memory, never quotes the file (a link to a secret), names the line."""
    if plant in ("fifo", "zero"):  # a FIFO or /dev/zero read would hang or fill memory: a subprocess
        tmp_path, done = request.getfixturevalue("calibrated_from_devices")[plant]
    else:
        study = _with_data(made, tmp_path, plant)
        done = run_cli("calibrate", str(study), "-o", str(tmp_path / "out"))
    assert done.returncode == 2, done.stderr[-2000:]
    assert expected in done.stderr and "calibrate.data" in done.stderr, done.stderr
    assert "s3cr3t" not in done.stderr and "alice" not in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "out").exists()  # refused before anything was written


# --- item 8: optimize honours SIGINT / SIGTERM, says the truth, writes its outputs as one set -------------


class Search:
    """``crashstudy optimize`` with a budget too large to finish, its progress read as it comes."""

    def __init__(self, study: Path, out: Path) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "crashstudy.cli", "optimize", str(study), "-o", str(out)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            preexec_fn=limited,
        )
        assert self.proc.stderr is not None
        os.set_blocking(self.proc.stderr.fileno(), False)
        self.err = b""

    def wait_generation(self, n: int, timeout: float = 300) -> None:
        t0 = time.monotonic()
        while b"generation %d:" % n not in self.err:
            assert self.proc.stderr is not None
            self.err += self.proc.stderr.read() or b""
            if self.proc.poll() is not None:
                pytest.fail(
                    f"optimize ended (exit {self.proc.returncode}) before generation {n}: {self.err[-2000:]!r}"
                )
            if time.monotonic() - t0 > timeout:
                self.proc.kill()
                pytest.fail(f"no generation {n} within {timeout} s")
            time.sleep(0.01)

    def end(self, timeout: float = 120) -> tuple[int, str]:
        try:
            _, err = self.proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            pytest.fail(f"optimize did not stop within {timeout} s of the signal")
        return self.proc.returncode, (self.err + err).decode()


@pytest.mark.parametrize("signals", [[signal.SIGINT], [signal.SIGTERM, signal.SIGTERM]])
def test_optimize_stops_on_a_signal_and_leaves_the_earlier_outputs_whole(
    made: dict[str, Path], tmp_path: Path, signals: list[int]
) -> None:
    """A finished optimize of the same study is in the folder; a re-run with a budget of 10^6 is stopped
    in its search. It ends with 130, says it cannot resume (not 'continue with --resume'), and the
    folder holds the earlier optimum.yaml, history.csv and results unchanged, which still agree."""
    out = tmp_path / "O"
    assert main(["optimize", str(made["opt"]), "-o", str(out)]) == 0
    before = snapshot(out)
    big = yaml.safe_load(made["opt"].read_text())
    big["optimize"]["budget"] = 1_000_000
    big["model"] = str(made["model"])
    study = tmp_path / "big.yaml"
    study.write_text(yaml.safe_dump(big, sort_keys=False))
    search = Search(study, out)
    search.wait_generation(1)
    for s in signals:
        search.proc.send_signal(s)
    code, err = search.end()
    assert code == 130, err[-2000:]
    assert "cannot resume" in err and "--resume" not in err and "Traceback" not in err, err[-2000:]
    assert snapshot(out) == before
    opt = yaml.safe_load((out / "optimum.yaml").read_text())
    s = pd.read_parquet(out / "summary.parquet")
    assert s["nodes.b.mass"].iloc[0] == pytest.approx(opt["variables"]["nodes.b.mass"])
    assert s["peak_force.s"].iloc[0] == pytest.approx(peak_force(s["nodes.b.mass"].iloc[0]), rel=2e-3)
    assert len(pd.read_csv(out / "history.csv")) == opt["evaluations"]
