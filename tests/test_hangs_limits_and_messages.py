"""Fault testing, issue 14 items 14, 15, 16 and the unclear messages: each test failed before its fix.

- 14: ``--scheduler`` at a listener that accepts and never answers gives up after the stated timeout
  (exit 2); a FIFO, a device or a directory as a file to read is refused before it is opened.
- 15: big documents: parsed once per command and refused by their count of values with a message
  that names the limit and how to raise it (not "a possible alias bomb"); hints computed only for the
  problems that are shown.
- 16: a run whose work (springs x time steps, summed over variants) is beyond a limit is refused
  before it starts, naming the estimate and ``CRASHSTUDY_MAX_WORK``.
- messages: a path too long, a directory or a device as model path, a metric that failed by NaN in
  ``compare``'s summary line, ``summary --head -1``.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from crashstudy.errors import InputError
from crashstudy.schema import yamlio
from crashstudy.study.plan import load_study
from helpers import (  # noqa: E402 - shared helpers
    TINY_MODEL,
    Cli,
    K,
    assert_exit_2,
    reseal,
    run_cli_in_one_process,
    run_cli_process,
)

MODEL = TINY_MODEL  # the tiny model of helpers.py (K = 2e4 N/m, 2 kg at 1 m/s)
STUDY = "name: tiny-study\nmodel: model.yaml\nmatrix:\n  nodes.body.mass: [1.0, 2.0]\n"


def write(folder: Path, study: str = STUDY, model: str = MODEL) -> Path:
    (folder / "model.yaml").write_text(model)
    path = folder / "study.yaml"
    path.write_text(study)
    return path


# ------------------------------------------------------------------------------------------------
# item 14: a scheduler that never answers; FIFOs and devices
# ------------------------------------------------------------------------------------------------


@pytest.fixture
def silent_listener() -> Iterator[str]:
    """A TCP listener on 127.0.0.1 that accepts connections and never sends a byte."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    server.settimeout(0.2)
    accepted: list[socket.socket] = []
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                accepted.append(server.accept()[0])
            except OSError:
                pass

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    stop.set()
    thread.join(5)
    for conn in accepted:
        conn.close()
    server.close()


def test_a_scheduler_that_accepts_and_never_answers_exits_2_after_the_stated_timeout(
    tmp_path: Path, silent_listener: str
) -> None:
    pytest.importorskip("distributed")
    study = write(tmp_path)
    # the command line with the connect timeout at 1 s (10 s by default); it hung for good before the fix:
    # the subprocess timeout (60 s) only stops a hang, the test asserts no time
    code = (
        "import sys, crashstudy.run.dask_backend as d; d.CONNECT_TIMEOUT = 1.0; from crashstudy.cli.main import main; "
        "sys.exit(main(sys.argv[1:]))"
    )
    p = subprocess.run(
        [
            sys.executable,
            "-c",
            code,
            "run",
            str(study),
            "-o",
            str(tmp_path / "out"),
            "--scheduler",
            silent_listener,
            "--progress",
            "off",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert_exit_2(
        p,
        f"--scheduler: cannot connect to a Dask scheduler at '{silent_listener}' (waited up to 1 s)",
        "accepted the connection but sent no Dask handshake",
    )
    assert not (tmp_path / "out").exists()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes")
def test_a_fifo_as_the_file_to_validate_is_refused_before_it_is_opened(tmp_path: Path, cli: Cli) -> None:
    fifo = tmp_path / "model.yaml"
    os.mkfifo(fifo)
    p = run_cli_process("validate", fifo)  # opened, it would wait for a writer for good (stopped at 600 s)
    assert_exit_2(p, f"{fifo}: not a regular file: it is a named pipe (FIFO); expected a YAML file")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes")
def test_a_fifo_device_or_directory_as_model_path_is_named_as_what_it_is(tmp_path: Path, cli: Cli) -> None:
    os.mkfifo(tmp_path / "pipe.yaml")
    (tmp_path / "folder.yaml").mkdir()
    cases = {
        "pipe.yaml": "not a regular file: it is a named pipe (FIFO)",
        "/dev/null": "a character device",
        "folder.yaml": "is a directory, expected a YAML file",
    }
    studies = []
    for model in cases:
        studies.append(tmp_path / f"study-{len(studies)}.yaml")
        studies[-1].write_text(STUDY.replace("model.yaml", model))
    # in a subprocess (one for the three): a FIFO opened would wait for a writer for good
    done = run_cli_in_one_process(*[("validate", study) for study in studies], timeout=300)
    for (name, p), expect in zip(zip(studies, done, strict=True), cases.values(), strict=True):
        assert_exit_2(p, f"{name.name}:2: model: model path ", expect)
        assert "not found" not in p.stderr  # was "model file not found" for an existing folder or device


# ------------------------------------------------------------------------------------------------
# item 15: big documents
# ------------------------------------------------------------------------------------------------


def chain_model(n: int) -> str:
    """A 1-D chain of ``n`` nodes (the first fixed), a linear spring between neighbours."""
    lines = ["name: chain", "nodes:", "  n0: {position: [0.0], fixed: true}"]
    lines += [f"  n{i}: {{position: [{0.1 * i:.1f}], mass: 1.0}}" for i in range(1, n)]
    lines += ["springs:"]
    lines += [
        f"  s{i}: {{nodes: [n{i - 1}, n{i}], material: {{type: linear_elastic, stiffness: 1000.0}}}}"
        for i in range(1, n)
    ]
    return "\n".join(lines + ["end_time: 0.01", "output: {histories: none}"]) + "\n"


def values_of(n: int) -> int:
    """Values in chain_model(n), counted by hand: each key, scalar, list and mapping is one."""
    fixed = (
        1 + 2 + 2 + 2 + 2 + 4
    )  # top mapping; name: v; nodes: {}; springs: {}; end_time: v; output: {histories: v}
    node = 7  # key, mapping, 'position', list, number, 'fixed' / 'mass', its value
    spring = 12  # key, mapping, 'nodes', list, 2 ids, 'material', mapping, 'type', value, 'stiffness', value
    return fixed + node * n + spring * (n - 1)


def test_a_chain_over_the_value_limit_is_refused_naming_the_limit_and_how_to_raise_it(
    tmp_path: Path, cli: Cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    n = 600  # over a limit of 10,000 set by the variable: counted as 6000 nodes over 100,000 are, 10x cheaper
    text = chain_model(n)
    (tmp_path / "chain.yaml").write_text(text)
    monkeypatch.setenv("CRASHSTUDY_MAX_VALUES", "10000")
    assert values_of(n) == 11_401  # 19 per node and its spring: over 10,000
    p = cli("validate", tmp_path / "chain.yaml")
    assert_exit_2(
        p,
        "document too large: more than 10,000 values",
        "set the environment variable CRASHSTUDY_MAX_VALUES to read more",
    )
    assert "alias bomb" not in p.stderr  # was: "refusing a possible alias bomb" for a plain model
    monkeypatch.setenv("CRASHSTUDY_MAX_VALUES", str(values_of(n)))  # the limit is inclusive and exact
    doc = yamlio.load_yaml(tmp_path / "chain.yaml")
    assert len(doc.data["nodes"]) == n and len(doc.data["springs"]) == n - 1
    monkeypatch.setenv("CRASHSTUDY_MAX_VALUES", str(values_of(n) - 1))
    with pytest.raises(InputError, match=f"more than {values_of(n) - 1:,} values"):
        yamlio.loads_yaml(text + "# not cached: another text\n")
    monkeypatch.setenv("CRASHSTUDY_MAX_VALUES", "2e5x")
    with pytest.raises(InputError, match="CRASHSTUDY_MAX_VALUES: expected a whole number of values > 0"):
        yamlio.load_yaml(tmp_path / "chain.yaml")


def test_a_document_with_far_more_values_than_the_limit_is_refused_before_it_is_composed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    if yamlio.CParser is None:
        pytest.skip("PyYAML without libyaml: the document is composed up to the limit")
    monkeypatch.setenv("CRASHSTUDY_MAX_VALUES", "1000")
    text = "a: [" + ", ".join(["1"] * 5000) + "]\n"  # events: 4 + 2 (map) + 1 + 2 (list) + 5000
    composed: list[int] = []
    monkeypatch.setattr(yamlio._Counting, "compose_document", lambda self: composed.append(1))
    with pytest.raises(InputError, match=r"at least 2,502 values .*at most 1,000"):  # (5009 - 4) // 2
        yamlio.loads_yaml(text)
    assert composed == []


def test_validate_parses_a_big_study_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from crashstudy.cli.main import main

    masses = [1.0 + 1e-4 * i for i in range(20_000)]  # 20,000 variants; before: parsed 3 times by validate
    study = write(tmp_path, f"name: big\nmodel: model.yaml\nmatrix:\n  nodes.body.mass: {masses}\n")
    parsed: list[str] = []
    real = yamlio._parse
    monkeypatch.setattr(yamlio, "_parse", lambda text, file: parsed.append(file) or real(text, file))
    assert main(["validate", str(study)]) == 0
    assert capsys.readouterr().out.startswith(f"{study}: valid study (20000 variants)")
    assert parsed.count(str(study)) == 1, parsed
    plan = load_study(study)  # a copy of the parsed data each time: changing one changes no other
    np.testing.assert_array_equal(plan.axes[0].values, masses)


def test_only_the_shown_unknown_keys_get_a_did_you_mean_hint(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import difflib

    from crashstudy.schema import report

    calls: list[str] = []
    real = difflib.get_close_matches
    monkeypatch.setattr(
        difflib, "get_close_matches", lambda word, *a, **k: calls.append(word) or real(word, *a, **k)
    )
    keys = "\n".join(f"  k{i}: 1" for i in range(3000))
    study = write(tmp_path, f"name: s\nmodel: model.yaml\nset:\n{keys}\n")
    with pytest.raises(InputError) as info:
        load_study(study)
    # issue 24 item 10 (fail fast): the first 5 unknown keys, then how many more (every one of 3000 before)
    assert len(info.value.problems) == 6
    assert info.value.problems[-1].message == "and 2,995 more keys under set: that are not model fields"
    assert len(calls) <= report.MAX_HINTED  # was 3000 (68 s for 499,000 keys)


# ------------------------------------------------------------------------------------------------
# item 16: runs that would take days
# ------------------------------------------------------------------------------------------------


def test_a_model_of_1e14_element_steps_is_refused_by_validate_and_simulate(tmp_path: Path, cli: Cli) -> None:
    # end_time 1e9 s at a fixed dt of 1e-5 s: 1e14 steps of its one spring (2.5 s of warm-up compile would
    # then be followed by about a day of computing)
    model = MODEL.replace("end_time: 0.05", "end_time: 1.0e9\ntime_step: {dt: 1.0e-5}").replace(
        "histories: none", "histories: none, interval: 1.0e6"
    )
    (tmp_path / "long.yaml").write_text(model)
    for command in ("validate", "simulate"):
        p = cli(command, tmp_path / "long.yaml", *(("-o", tmp_path / "out") if command == "simulate" else ()))
        assert_exit_2(
            p,
            "long.yaml:10: end_time: the run would take about 1e+14 element-steps",
            "1.16 days",
            "at most 1e+13",
            "CRASHSTUDY_MAX_WORK",
        )  # 1e14 / 1e9 per s = 1e5 s = 1.157 days
    assert not (tmp_path / "out").exists()


def test_an_end_time_axis_up_to_1e12_is_refused_with_the_estimate_and_runs_with_the_limit_raised(
    tmp_path: Path, cli: Cli
) -> None:
    study = write(
        tmp_path,
        "name: s\nmodel: model.yaml\nmatrix:\n  end_time: [0.05, 1.0, 1.0e12]\n"
        "  nodes.body.mass: [1.0, 2.0]\n",
    )
    plan_work = []
    for env in ({}, {"CRASHSTUDY_MAX_WORK": "1e20"}):
        with pytest.MonkeyPatch.context() as mp:  # read when the plan is made, not at import: in this process
            for name, value in env.items():
                mp.setenv(name, value)
            plan_work.append(cli("validate", study))
    assert_exit_2(
        plan_work[0],
        "study.yaml:4: matrix.end_time: the run would take about",
        "element-steps",
        "the longest variant (4) takes",
        "CRASHSTUDY_MAX_WORK",
    )
    assert plan_work[1].returncode == 0 and "about" in plan_work[1].stdout, plan_work[1].stderr
    # independent count (docs/solver.md): dt_crit = 0.99 * 2 / sqrt(2 K / m) (one spring, one mass), the default
    # tolerance 1e-3 takes dt = 2 sqrt(1e-3 / 2) dt_crit, made the largest step that divides the sampling
    # interval (1e12 / 1000 = 1e9); steps = end_time / dt for each variant
    interval = 1.0e12 / 1000
    total = 0.0
    for end in (0.05, 1.0, 1.0e12):
        for m in (1.0, 2.0):
            step = 2.0 * np.sqrt(1e-3 / 2.0) * 0.99 * 2.0 / np.sqrt(2.0 * K / m)
            dt = interval / np.ceil(interval / step - 1e-9)
            total += np.ceil(end / dt - 1e-9)
    os.environ["CRASHSTUDY_MAX_WORK"] = "1e20"
    try:
        plan = load_study(study)
    finally:
        del os.environ["CRASHSTUDY_MAX_WORK"]
    assert plan.work == pytest.approx(total, rel=1e-12)
    assert f"about {total:.3g} element-steps" in plan_work[0].stderr


def test_a_small_study_reports_no_work_line_and_passes(tmp_path: Path, cli: Cli) -> None:
    p = cli("validate", write(tmp_path))
    assert p.returncode == 0 and p.stdout == f"{tmp_path / 'study.yaml'}: valid study (2 variants)\n", (
        p.stderr
    )


# ------------------------------------------------------------------------------------------------
# unclear messages
# ------------------------------------------------------------------------------------------------


def test_a_path_too_long_is_invalid_input_not_a_failed_write(tmp_path: Path, cli: Cli) -> None:
    long = tmp_path / ("c" * 300)
    for args in (("summary", long), ("compare", long, long), ("run", write(tmp_path), "-o", long)):
        p = cli(*args)
        assert_exit_2(p, "path too long (the system allows 255 bytes per name and 4096 per path)")
        assert "cannot write results" not in p.stderr
    study = tmp_path / "s2.yaml"
    study.write_text(STUDY.replace("model.yaml", "m" * 300 + ".yaml"))
    assert_exit_2(cli("validate", study), "s2.yaml:2: model: cannot use the model path", "File name too long")


def test_compare_names_metrics_that_failed_by_nan_instead_of_a_zero_rel_diff(
    tmp_path: Path, cli: Cli
) -> None:
    from crashstudy.run.runner import run_plan

    plan = load_study(write(tmp_path))
    run_plan(plan, tmp_path / "base", progress=False)
    run_plan(plan, tmp_path / "new", progress=False)
    new = tmp_path / "new"
    column = "peak_force.spring"
    for name in ("summary.parquet", "summary.csv"):
        if (new / name).exists():
            df = pd.read_parquet(new / name) if name.endswith("parquet") else pd.read_csv(new / name)
            df.loc[1, column] = np.nan
            df.to_parquet(new / name, index=False) if name.endswith("parquet") else df.to_csv(
                new / name, index=False
            )
    reseal(new)  # as if the run had written the NaN (an edited file is refused: test_write_read.py)
    p = cli("compare", new, tmp_path / "base")
    assert p.returncode == 1, p.stdout + p.stderr
    line = next(ln for ln in p.stdout.splitlines() if ln.startswith(f"  {column}:"))
    assert line.startswith(f"  {column}: 1 of 2 variants, 1 a number on one side and NaN on the other"), line
    assert "0.000e+00" not in line  # was "largest |rel diff| 0.000e+00"


def test_summary_head_minus_one_exits_2(tmp_path: Path, cli: Cli) -> None:
    from crashstudy.run.runner import run_plan

    run_plan(load_study(write(tmp_path)), tmp_path / "out", progress=False)
    assert_exit_2(
        cli("summary", tmp_path / "out", "--head", "-1"), "--head: expected 0 (every row) or a number"
    )
