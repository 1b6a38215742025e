"""The command line's own process ends without the interpreter's teardown (cli/process_end.py): the
results, the printed lines, the exit code and the ``atexit`` handlers are those of a normal exit; only
the finalization of modules and objects (0.5-0.6 CPU s after a 10^6-variant run) is skipped."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from helpers import MASSES, TINY_MODEL, TINY_STUDY, K, peak_force

# the installed command's invocation (``main()`` without argv), with an atexit handler and an object that
# only the interpreter's teardown would finalize
_ENTRY = """\
import atexit, sys
atexit.register(lambda: print("atexit handler ran"))
class Held:
    def __del__(self):
        print("interpreter teardown ran")
held = Held()
from crashstudy.cli.main import main
sys.argv = ["crashstudy", *sys.argv[1:]]
raise SystemExit(main())
"""


def _entry(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", _ENTRY, *args], capture_output=True, text=True, cwd=cwd, timeout=600
    )


@pytest.fixture()
def study(tmp_path: Path) -> Path:
    (tmp_path / "model.yaml").write_text(TINY_MODEL)
    (tmp_path / "study.yaml").write_text(TINY_STUDY)
    return tmp_path


def test_run_ends_without_teardown_and_keeps_everything(study: Path) -> None:
    p = _entry("run", "study.yaml", "-o", "out", cwd=study)
    assert p.returncode == 0, p.stderr
    assert "wrote out/results.nc" in p.stdout  # printed before the end, flushed
    assert "atexit handler ran" in p.stdout
    assert "interpreter teardown ran" not in p.stdout  # the teardown skipped (printed before the change)
    import crashstudy

    res = crashstudy.open_results(study / "out")  # the manifest checks every file: written and closed
    got = res.summary["peak_force.spring"].to_numpy(dtype=float)
    want = np.array([peak_force(K, m) for m in MASSES])
    np.testing.assert_allclose(got, want, rtol=2e-3)  # closed form of the undamped oscillator


def test_exit_codes_and_other_commands_unchanged(study: Path) -> None:
    (study / "bad.yaml").write_text(TINY_STUDY.replace("nodes.body.mass", "nodes.nobody.mass"))
    p = _entry("run", "bad.yaml", "-o", "bad", cwd=study)
    assert p.returncode == 2 and "error: invalid input" in p.stderr, p.stderr
    assert "atexit handler ran" in p.stdout and "interpreter teardown ran" not in p.stdout
    p = _entry("run", "study.yaml", "--dry-run", cwd=study)  # another path through run: same end
    assert p.returncode == 0 and "3 variants" in p.stdout, p.stderr
    p = _entry("--version", cwd=study)  # argparse's exit: the interpreter ends as before
    assert p.returncode == 0 and "interpreter teardown ran" in p.stdout
