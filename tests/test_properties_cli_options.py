"""Property-based tests (hypothesis) of the command line: random options of ``compare`` and ``summary``
exit 0, 1 or 2 without a traceback, through :func:`crashstudy.cli.main` in this process, as a user's
command would run.

The number of generated inputs that actually ran is counted (property_inputs.py) and printed at the end of
the module (run with ``-s`` to see it); docs/robustness.md quotes it. How many examples each property
draws: property_inputs.py."""

from __future__ import annotations

import contextlib
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers import run_main
from property_inputs import COUNTS, SMALL_MODEL, _report_counts  # noqa: F401 - _report_counts: autouse, prints the counts
from strategies import examples

# ------------------------------------------------------------------------------------------------
# 6. random options of `compare` and `summary`
# ------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def two_results(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("options")
    (root / "model.yaml").write_text(SMALL_MODEL)
    (root / "study.yaml").write_text(
        "name: opts\nmodel: model.yaml\nmatrix:\n  nodes.body.mass: [800.0, 900.0, "
        "1000.0]\n  impact_velocity: [5.0, 10.0]\n"
    )
    for name in ("new", "base"):
        rc, _, err = run_main("run", str(root / "study.yaml"), "-o", str(root / name), "--progress", "off")
        assert rc == 0, err
    return root / "new", root / "base"


WORDS = st.sampled_from(
    [
        "peak",
        "peak_force",
        "crush",
        "body",
        "variant",
        "status",
        "nodes.body.mass",
        "x",
        "",
        "energy_error",
        "dt",
        "-1",
        "nan",
        "impact_velocity",
        "failure_reason",
        "zzz",
    ]
)
NUMBERS = st.sampled_from(
    ["0", "1", "-1", "1e-6", "0.5", "nan", "inf", "-inf", "1e308", "abc", "", "5", "100", "-3", "2.5"]
)


@st.composite
def options(draw: st.DrawFn, command: str) -> list[str]:
    picked = draw(
        st.lists(
            st.sampled_from(
                {
                    "summary": ["--sort", "--ascending", "--head", "--columns", "--variant"],
                    "compare": ["--rtol", "--atol", "--junit"],
                }[command]
            ),
            unique=True,
            max_size=4,
        )
    )
    args: list[str] = []
    for opt in picked:
        if opt == "--ascending":
            args.append(opt)
        elif opt == "--columns":
            args += [opt, *draw(st.lists(WORDS, min_size=1, max_size=3))]
        elif opt in ("--sort",):
            args += [opt, draw(WORDS)]
        elif opt == "--junit":
            args += [
                opt,
                draw(st.sampled_from(["report.xml", "summary.csv", "results.nc", "sub/none/r.xml"])),
            ]
        else:
            args.append(f"{opt}={draw(NUMBERS)}")
    return args


@settings(max_examples=examples(40, 120), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.sampled_from(["summary", "compare"]), st.data())
def test_random_options_of_compare_and_summary_exit_0_1_or_2_without_a_traceback(
    two_results: tuple[Path, Path], command: str, data: st.DataObject
) -> None:
    """Draws 40 command lines (120 under ``HYPOTHESIS_PROFILE=explore``, new ones on each run)."""
    new, base = two_results
    args = data.draw(options(command), label="options")
    with tempfile.TemporaryDirectory(prefix="crashstudy-prop-") as tmp, contextlib.chdir(tmp):
        # argparse's exit (a value that is not a number, an option without its value) is run_main's exit code
        rc, out, err = run_main(command, str(new), *((str(base),) if command == "compare" else ()), *args)
    COUNTS[f"{command}_options_run"] += 1
    COUNTS[f"{command}_options_exit_{rc}"] += 1
    assert rc in ((0, 2) if command == "summary" else (0, 1, 2)), (args, rc, out, err)
    assert "Traceback" not in err
    if (
        rc == 2 and err
    ):  # ours, or argparse's usage line for a value that is no number / an option without one
        assert err.startswith(("error: invalid input\n", "usage: crashstudy ")), (args, err)
    if rc == 1:  # compare only (two runs of one study): a verdict, never a crash
        assert out.splitlines()[-1].startswith("FAILED"), out
