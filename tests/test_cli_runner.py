"""The tests' command-line runners (helpers.py): ``run_cli`` runs ``crashstudy`` in the test's own process,
``run_cli_process`` in a fresh interpreter as a user does. The in-process one must print, exit and write as
the real command does (the subprocess is the independent truth here), fail the test when an exception
escapes ``main`` (a user would see a traceback), and leave the test process as it found it."""

from __future__ import annotations

import os
import signal
import warnings
from pathlib import Path

import pytest

from crashstudy import interrupt
from crashstudy.cli import main as cli_main
from crashstudy.errors import CrashstudyWarning
from helpers import TINY_MODEL, TINY_STUDY, run_cli, run_cli_process

COMMANDS = [
    ("validate", "study.yaml"),  # valid, relative path as given
    ("validate", "broken.yaml"),  # invalid input: exit 2, file and line
    ("run", "study.yaml", "--dry-run", "-o", "out"),
    ("run", "study.yaml", "--frobnicate"),  # argparse: usage and exit 2 through SystemExit
    ("--version",),  # argparse: exit 0 through SystemExit
    ("summary", "nowhere"),  # no result folder: exit 2
]


def test_in_process_command_prints_and_exits_as_the_installed_command(tmp_path: Path) -> None:
    (tmp_path / "model.yaml").write_text(TINY_MODEL)
    (tmp_path / "study.yaml").write_text(TINY_STUDY)
    (tmp_path / "broken.yaml").write_text(TINY_MODEL.replace("mass: 2.0}", "mass: 2.0"))
    for argv in COMMANDS:
        here = run_cli(*argv, cwd=tmp_path)
        real = run_cli_process(*argv, cwd=tmp_path)
        assert (here.returncode, here.stdout, here.stderr) == (real.returncode, real.stdout, real.stderr), (
            argv
        )
    assert not (tmp_path / "out").exists()


def test_an_exception_escaping_main_fails_the_test(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    def broken(args: object) -> int:
        raise ZeroDivisionError("a bug: the user would see a traceback")

    monkeypatch.setitem(cli_main.COMMANDS, "validate", broken)
    with pytest.raises(ZeroDivisionError, match="a bug"):
        run_cli("validate", "x.yaml", cwd=tmp_path)


def test_a_crashstudy_warning_prints_one_line_as_for_a_user(monkeypatch: pytest.MonkeyPatch) -> None:
    """pytest turns CrashstudyWarning into an error (pyproject.toml); a user's command prints it."""

    def warns(args: object) -> int:
        warnings.warn("the spring is soft", CrashstudyWarning, stacklevel=1)
        return 0

    monkeypatch.setitem(cli_main.COMMANDS, "validate", warns)
    done = run_cli("validate", "x.yaml")
    assert (done.returncode, done.stdout, done.stderr) == (0, "", "warning: the spring is soft\n")


def test_the_runner_puts_back_what_a_command_changes(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    def changes(args: object) -> int:
        os.environ["CRASHSTUDY_RUNNER_PROBE"] = "set"
        warnings.simplefilter("ignore")
        interrupt.request()
        return 0

    monkeypatch.setitem(cli_main.COMMANDS, "validate", changes)
    before = (
        os.getcwd(),
        dict(os.environ),
        list(warnings.filters),
        warnings.showwarning,
        signal.getsignal(signal.SIGINT),
        signal.getsignal(signal.SIGTERM),
    )
    assert run_cli("validate", "x.yaml", cwd=tmp_path).returncode == 0
    after = (
        os.getcwd(),
        dict(os.environ),
        list(warnings.filters),
        warnings.showwarning,
        signal.getsignal(signal.SIGINT),
        signal.getsignal(signal.SIGTERM),
    )
    assert after == before
    assert not interrupt.STOP.is_set()


def test_validate_and_schema_import_no_table_array_or_plot_library(tmp_path: Path) -> None:
    """A fresh process (the modules a command imports are what is counted): ``validate`` of a model or a
    study and ``schema`` import none of pandas, xarray, netCDF4, pyarrow, dask, matplotlib, scipy, numba
    (``validate model.yaml`` imported the runner and with it pandas, xarray and netCDF4: 1.5 s CPU, now 0.7 s)."""
    import json
    import subprocess
    import sys

    (tmp_path / "model.yaml").write_text(TINY_MODEL)
    (tmp_path / "study.yaml").write_text(TINY_STUDY)
    code = (
        "import json, sys\nfrom crashstudy.cli.main import main\n"
        "heavy = ('pandas', 'xarray', 'netCDF4', 'pyarrow', 'dask', 'matplotlib', 'scipy', 'numba')\nseen = {}\n"
        "for argv in json.loads(sys.argv[1]):\n    main(argv)\n"
        "    seen[' '.join(argv)] = [m for m in heavy if m in sys.modules]\n"
        "print(json.dumps(seen))\n"
    )
    commands = [["validate", "model.yaml"], ["validate", "study.yaml"], ["schema", "model"]]
    done = subprocess.run(
        [sys.executable, "-c", code, json.dumps(commands)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout.splitlines()[-1])
    assert seen == {" ".join(c): [] for c in commands}, seen
