"""What the test modules share: running a model (as YAML text or a dict) with a chosen kernel, the command
line in this process or in a subprocess, and the one comparer of kernel outputs. Test modules import from
here (and from ``twins.py``, ``twin_models.py``, ``model_parts.py``, ``strategies.py``), never from each other."""

from __future__ import annotations

import contextlib
import copy
import functools
import io
import locale
import math
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from crashstudy.arrays.batch import build_batch
from crashstudy.errors import InputError
from crashstudy.kernel.output import KernelOutput
from crashstudy.schema import parse_model
from crashstudy.schema.yamlio import LoadedYaml, loads_yaml
from crashstudy.study.plan import Plan, plan_from_model

ROOT = Path(__file__).resolve().parents[1]
STUDIES = ROOT / "studies"

LINEAR_SPRING = """\
name: lin
units: SI
nodes:
  anchor: {position: [0.0], fixed: true}
  body: {position: [0.1], mass: 2.0}
springs:
  s: {nodes: [anchor, body], material: {type: linear_elastic, stiffness: 2.0e4}}
initial_velocity: {body: [1.0]}
end_time: 0.1
"""  # a 2 kg body on a 2e4 N/m spring at 1 m/s: the optimize / calibrate / block-check tests' model


def noisy_spring_force(k: float, m: float, noise: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """(t, force) of k [N/m], m [kg] set moving at 1 m/s, integrated by scipy's RK45 (rtol 1e-10) and
    sampled at 201 points over 0.1 s, with Gaussian noise of ``noise`` x the peak force (seed 0)."""
    from scipy.integrate import solve_ivp

    sol = solve_ivp(
        lambda t, y: [y[1], -k / m * y[0]], (0.0, 0.1), [0.0, 1.0], rtol=1e-10, atol=1e-12, dense_output=True
    )
    t = np.linspace(0.0, 0.1, 201)
    force = k * sol.sol(t)[0]
    return t, force + np.random.default_rng(0).normal(0.0, noise * np.abs(force).max(), t.size)


def dump(data: dict[str, Any]) -> str:
    """A model or study dict as YAML text (for files and for assertion messages)."""
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120)


def model_plan(model: str | dict[str, Any]) -> Plan:
    """A one-variant plan from YAML text or a plain dict, validated like a file. A dict of Python numbers
    is validated as it is (a YAML round trip takes seconds for a 1000-node chain); one that is not valid
    so, e.g. read by ``yaml.safe_load``, which leaves ``3.0e4`` a string, goes through crashstudy's YAML
    reader as a file would."""
    if isinstance(model, dict):
        try:
            return plan_from_model(
                parse_model(LoadedYaml(model, "", f"<{model.get('name', 'test model')}>", {}))
            )
        except InputError:
            model = yaml.safe_dump(model, sort_keys=False)
    return plan_from_model(parse_model(loads_yaml(model, file="<test model>")))


def model_batch(
    model: str | dict[str, Any], variants: dict[str, list[float]] | None = None
) -> tuple[Any, Plan]:
    """(batch, plan) of a model with axis values per variant ({path: [v0, v1, ...]}; one variant without)."""
    from crashstudy.arrays.compiler import apply_axis

    plan = model_plan(model)
    topo = plan.topology
    n = len(next(iter(variants.values()))) if variants else 1
    P = np.repeat(plan.base[:, None], n, axis=1)
    for path, vals in (variants or {}).items():
        apply_axis(P, topo.paths[path], np.asarray(vals, dtype=float))
    batch, _ = build_batch(topo, P, plan.interval)
    return batch, plan


def run_model(
    model: str | dict[str, Any], kernel: str = "compiled", variants: dict[str, list[float]] | None = None
) -> tuple[KernelOutput, Any, Plan]:
    """Run a model (optionally with axis values per variant: {path: [v0, v1, ...]}).

    Returns (kernel output, batch, plan); histories follow the model's ``output.histories``.
    """
    from crashstudy.run.runner import run_kernel

    batch, plan = model_batch(model, variants)
    out = run_kernel(batch, plan.topology.histories, plan.n_out, kernel)
    return out, batch, plan


def generated_parts_model(
    dt: float, end_time: float, interval: float
) -> tuple[dict[str, Any], dict[str, list[float]]]:
    """(model, {axis path: values}) of the one side-by-side model of :func:`models.generated_parts` as
    :func:`generated_part` runs it (its generated kernel is compiled at start-up, tests/conftest.py): a
    study of this model with these axes (any values, any step) runs that same compiled kernel."""
    from model_parts import disjoint
    from models import SCALES, generated_parts

    model = disjoint(generated_parts())
    histories = ["wall_force", "acceleration", "velocity", "wall_energy"]  # what the callers read (and the
    # energies that come with wall_energy): less source than "all", 23 instead of 26 CPU s of compile
    model.update(
        end_time=end_time, time_step={"dt": dt}, output={"interval": interval, "histories": histories}
    )
    scales = {path.replace("curves.c.", "curves.scaled-c."): values for path, values in SCALES.items()}
    return model, scales


@functools.cache
def _generated_parts_run(dt: float, end_time: float, interval: float) -> tuple[KernelOutput, Plan]:
    model, scales = generated_parts_model(dt, end_time, interval)
    out, _, plan = run_model(model, "generated", variants=scales)
    return out, plan


def generated_part(part: str, like: dict[str, Any], every_variant: bool = False) -> KernelOutput:
    """Part ``part`` of :func:`models.generated_parts` run by the generated kernel with the step, end time
    and output interval that the model ``like`` (that part alone) gets, as if it had run alone (its nodes,
    springs and walls; per-variant numbers such as ``status`` and ``energy_error`` are the whole model's),
    its variant 0 (all four variants of :data:`models.SCALES` with ``every_variant``).
    Every caller runs the same model shape, so the generated kernel compiles once for all of them (and
    loads from the kernel cache in other processes); runs are cached per (step, end time, interval)."""
    from model_parts import part_of

    batch, plan = model_batch(like)
    out, whole = _generated_parts_run(float(batch.dt[0]), float(like["end_time"]), float(plan.interval))
    got = part_of(out, whole, part)
    if every_variant:
        return got
    first = copy.copy(got)  # variant 0 (the parts other than ``scaled`` are the same in every variant)
    for name, value in vars(got).items():
        if isinstance(value, np.ndarray):
            setattr(first, name, value[..., :1])
    first.histories = {h: a[..., :1] for h, a in got.histories.items()}
    return first


def run_cli(
    *args: str | Path, cwd: Path | None = None, timeout: float | None = None
) -> subprocess.CompletedProcess[str]:
    """``crashstudy ARGS`` run IN THIS PROCESS as the installed command runs it (``python -m crashstudy.cli``):
    what it prints on stdout and stderr, its exit code (``SystemExit`` of argparse included), in folder
    ``cwd``; returned as the CompletedProcess of :func:`run_cli_process`. It saves a fresh interpreter's
    start (2 s of CPU importing numpy, numba, xarray, ...) per call. An exception escaping ``main`` would be
    a user's traceback: it is raised here and fails the test. What the call changes in this process is put
    back (:func:`_as_its_own_process`). ``timeout`` is accepted for the subprocess runner's callers and not
    enforced: a test of a hang or a timeout uses :func:`run_cli_process`."""
    from crashstudy.cli.main import main

    argv = [str(a) for a in args]
    encoding = locale.getpreferredencoding(
        False
    )  # a pipe's, as python sets up sys.stdout and sys.stderr for one
    out = io.TextIOWrapper(io.BytesIO(), encoding, errors="strict", write_through=True)
    err = io.TextIOWrapper(io.BytesIO(), encoding, errors="backslashreplace", write_through=True)
    with _as_its_own_process(cwd), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as exc:  # argparse's --help, --version and usage errors; as the interpreter exits
            if exc.code is None or isinstance(exc.code, int):
                rc = exc.code or 0
            else:
                print(exc.code, file=sys.stderr)
                rc = 1
    # decoded as subprocess.run(text=True) decodes a pipe: universal newlines ("\r" of a progress line is "\n")
    text = [
        s.buffer.getvalue().decode(encoding).replace("\r\n", "\n").replace("\r", "\n")  # type: ignore[attr-defined]
        for s in (out, err)
    ]
    return subprocess.CompletedProcess(["crashstudy", *argv], rc, *text)


def run_main(*argv: str | Path) -> tuple[int, str, str]:
    """``crashstudy ARGV`` in this process (:func:`run_cli`); returns (exit code, stdout, stderr)."""
    p = run_cli(*argv)
    return p.returncode, p.stdout, p.stderr


def run_cli_process(
    *args: str | Path, cwd: Path | None = None, timeout: float = 600
) -> subprocess.CompletedProcess[str]:
    """The installed command line in a subprocess (as a user runs it): for tests of what only a process
    boundary shows (signals, hangs and timeouts, variables read at import, pipes, the entry point)."""
    return subprocess.run(
        [sys.executable, "-m", "crashstudy.cli", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=timeout,
    )


def run_cli_in_one_process(
    *commands: tuple[str | Path, ...],
    cwd: Path | None = None,
    timeout: float = 600,
    preexec_fn: Callable[[], Any] | None = None,
) -> list[subprocess.CompletedProcess[str]]:
    """Several commands, each run as :func:`run_cli` runs it, one after the other in ONE subprocess that
    must end within ``timeout`` seconds: for inputs whose regression would hang or fill memory (the test
    fails at the timeout, a blow-up ends that process and not the test run) at one interpreter start
    (~1.5 s of CPU importing numpy, numba, xarray, ...) instead of one per command. An exception escaping
    a command's ``main`` is that command's traceback and exit code 1, as in a process of its own."""
    import json

    proc = subprocess.run(
        [sys.executable, "-c", _ONE_PROCESS, str(Path(__file__).resolve().parent)],
        input=json.dumps([[str(a) for a in argv] for argv in commands]),
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=timeout,
        preexec_fn=preexec_fn,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return [
        subprocess.CompletedProcess(["crashstudy", *map(str, argv)], rc, out, err)
        for argv, (rc, out, err) in zip(commands, json.loads(proc.stdout.splitlines()[-1]), strict=True)
    ]


_ONE_PROCESS = """\
import json, sys, traceback
sys.path.insert(0, sys.argv[1])
from helpers import run_cli
done = []
for argv in json.loads(sys.stdin.read()):
    try:
        p = run_cli(*argv)
        done.append([p.returncode, p.stdout, p.stderr])
    except BaseException:
        done.append([1, "", traceback.format_exc()])
print(json.dumps(done))
"""


@functools.cache
def shared_process_pool() -> Any:
    """One ``--jobs 2`` pool (``run.backends.ProcessPool(2)``: 2 spawned worker processes) for every test of
    this test process whose subject is the numbers the workers compute, not the pool's start (each start:
    2 processes importing numpy, numba and crashstudy, ~1.6 CPU s each). Never closed by a test:
    concurrent.futures shuts it down when the process exits."""
    from crashstudy.run.backends import ProcessPool

    return ProcessPool(2)


class SharedPool:
    """The shared pool handed to one run as its backend: its ``close`` leaves the pool running for the next."""

    def __init__(self, pool: Any) -> None:
        self.pool = pool

    def imap_unordered(self, fn: Callable[..., Any], tasks: Any) -> Any:
        return self.pool.imap_unordered(fn, tasks)

    def close(self) -> None:
        pass


def on_shared_pool(monkeypatch: Any) -> None:
    """``--jobs 2`` runs (``run.backends.make_backend(2)``) use :func:`shared_process_pool` until the test
    ends; other runs get their own backend as before."""
    import crashstudy.run.backends

    real = crashstudy.run.backends.make_backend

    def make_backend(jobs: int = 1, scheduler: str | None = None) -> Any:
        if (jobs, scheduler) != (2, None):
            return real(jobs, scheduler)
        return SharedPool(shared_process_pool())

    monkeypatch.setattr(crashstudy.run.backends, "make_backend", make_backend)


#: a fresh interpreter's warning filters (python without -W or PYTHONWARNINGS): pytest's own, e.g.
#: ``error::CrashstudyWarning`` of pyproject.toml, do not apply to a command a user runs
_FRESH_FILTERS = (
    ("default", DeprecationWarning, "__main__"),
    ("ignore", DeprecationWarning, ""),
    ("ignore", PendingDeprecationWarning, ""),
    ("ignore", ImportWarning, ""),
    ("ignore", ResourceWarning, ""),
)


@contextlib.contextmanager
def _as_its_own_process(cwd: Path | None) -> Iterator[None]:
    """Run the body as a command in a process of its own would: in folder ``cwd``, with a fresh
    interpreter's warning filters; afterwards put back the folder, the warning filters and
    ``showwarning`` (``main`` installs its one-line printer), the SIGINT/SIGTERM handlers ``main``
    installs, the stop request of :mod:`crashstudy.interrupt`, the environment, and the root logger."""
    import logging
    import os
    import signal
    import warnings

    from crashstudy import interrupt

    here, environ = os.getcwd(), dict(os.environ)
    handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    root = logging.getLogger()
    log_handlers, log_level = list(root.handlers), root.level
    try:
        with warnings.catch_warnings():
            warnings.resetwarnings()
            for action, category, module in reversed(_FRESH_FILTERS):
                warnings.filterwarnings(action, category=category, module=module)
            if cwd is not None:
                os.chdir(cwd)
            yield
    finally:
        os.chdir(here)
        for s, h in handlers.items():
            signal.signal(s, h)
        interrupt.reset()
        if dict(os.environ) != environ:
            os.environ.clear()
            os.environ.update(environ)
        root.handlers[:], root.level = log_handlers, log_level


# ------------------------------------------------------------------------------------------------
# a tiny model and study, and what every command-line fault test asserts (tests/test_study_input_faults.py, test_result_folder_faults.py, test_hangs_limits_and_messages.py)
# ------------------------------------------------------------------------------------------------

Cli = Callable[..., Any]

K, V0 = 2.0e4, 1.0  # spring stiffness [N/m], initial speed [m/s] of TINY_MODEL
TINY_MODEL = f"""\
name: tiny
nodes:
  anchor: {{position: [0.0], fixed: true}}
  body:   {{position: [0.1], mass: 2.0}}
springs:
  spring:
    nodes: [anchor, body]
    material: {{type: linear_elastic, stiffness: {K}}}
initial_velocity: {{body: [{V0}]}}
end_time: 0.05
output: {{histories: none}}
"""
MASSES = [1.0, 2.0, 3.0]
TINY_STUDY = f"name: tiny-study\nmodel: model.yaml\nmatrix:\n  nodes.body.mass: {MASSES}\n"


def peak_force(k: float, m: float) -> float:
    """Undamped mass on a spring from speed V0: amplitude V0 / omega, peak force V0 sqrt(k m)."""
    return V0 * math.sqrt(k * m)


def assert_exit_2(p: Any, *expect: str) -> None:
    """Exit 2, ``error: invalid input`` and the expected text; no traceback."""
    assert p.returncode == 2, (p.returncode, p.stdout, p.stderr)
    assert p.stderr.startswith("error: invalid input\n"), p.stderr
    assert "Traceback" not in p.stderr
    for text in expect:
        assert text in p.stderr, (text, p.stderr)


def reseal(folder: Path) -> None:
    """Record the folder's files as they are now in its manifest (a defect the run itself wrote)."""
    import json

    from crashstudy.results.integrity import write_manifest

    m = json.loads((folder / "manifest.json").read_text())
    write_manifest(folder, m["run_id"], [n for n in m["files"] if (folder / n).exists()])


# ------------------------------------------------------------------------------------------------
# the one comparer of kernel outputs
# ------------------------------------------------------------------------------------------------


def same_bits(r: np.ndarray, g: np.ndarray) -> bool:
    """Equal values, NaN where NaN, and the same sign of every zero (a summary's -0.0 prints as "-0.0")."""
    if not np.array_equal(r, g, equal_nan=r.dtype.kind == "f"):
        return False
    if r.dtype.kind != "f":
        return True
    zero = r == 0.0
    return bool(np.array_equal(np.signbit(r[zero]), np.signbit(g[zero])))


def output_differences(
    a: KernelOutput, b: KernelOutput, ia: Any = slice(None), ib: Any = slice(None)
) -> list[str]:
    """Names of what differs between variants ``ia`` of ``a`` and ``ib`` of ``b`` (default: all of both),
    bit for bit: every summary (:func:`same_bits`), each optional output (the metrics' step record,
    criteria) present in both or neither, the same histories with equal values and NaN where NaN (the
    sign of a zero sample may differ: the files hold +0.0 only)."""
    diff = []
    for f in fields(KernelOutput):
        if f.name == "histories":
            continue
        x, y = getattr(a, f.name), getattr(b, f.name)
        if x is None or y is None:
            if (x is None) != (y is None):
                diff.append(f"{f.name} (only in one of them)")
            continue
        if (
            f.name == "criteria"
        ):  # the crash criteria of each variant (metrics.record.ChunkCriteria), variant first
            same = set(x.values) == set(y.values) and np.array_equal(x.notes[ia], y.notes[ib])
            if not same or any(not same_bits(x.values[k][ia], y.values[k][ib]) for k in x.values):
                diff.append(f.name)
            continue
        x, y = np.asarray(x)[..., ia], np.asarray(y)[..., ib]
        if x.shape != y.shape or not same_bits(x, y):
            diff.append(f.name)
    if set(a.histories) != set(b.histories):
        diff.append(f"histories {sorted(set(a.histories) ^ set(b.histories))} (only in one of them)")
    for name in set(a.histories) & set(b.histories):
        x, y = a.histories[name][..., ia], b.histories[name][..., ib]
        if x.shape != y.shape or not np.array_equal(x, y, equal_nan=True):
            diff.append(f"history {name}")
    return diff


def assert_bitwise(ref: KernelOutput, got: KernelOutput) -> None:
    """``got`` equals ``ref`` bit for bit (:func:`output_differences`)."""
    diff = output_differences(ref, got)
    assert not diff, f"differ: {diff}"
