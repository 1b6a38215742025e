"""Fault testing, issue 14 items 8, 9, 10, 12 and 18: each test failed before its fix.

- 8: prescribed motion on a node that a rigid wall also holds is refused at validation.
- 9: a kill between the renames that end a re-run leaves a folder that ``Results`` refuses (a
  ``manifest.json`` written last names the run every final file belongs to).
- 10: a second run into a folder that a live run is writing exits 2 (``OUT/.crashstudy.lock``).
- 12: a ``results.nc.partial`` renamed by hand is not a finished result; a corrupted number in a
  partial is found by its checksum on ``--resume`` and that variant is computed again.
- 18: SIGKILL of the main process of ``run --jobs 2`` takes its pool workers with it.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import psutil
import pytest

from crashstudy.errors import InputError
from crashstudy.results.integrity import open_store
from crashstudy.results.store import Results
from crashstudy.run import runner
from crashstudy.study.plan import load_study
from helpers import MASSES, TINY_MODEL, TINY_STUDY, Cli, K, assert_exit_2, peak_force  # noqa: E402 - the shared tiny model

RTOL = 0.02  # the sampled peak of a harmonic oscillation at the default step: within 2 % of the analytic one


def write(folder: Path, study: str = TINY_STUDY, model: str = TINY_MODEL) -> Path:
    (folder / "model.yaml").write_text(model)
    path = folder / "study.yaml"
    path.write_text(study)
    return path


def assert_analytic(out: Path, k: float = K) -> None:
    """The folder's summary and dataset agree with each other and with the analytic peak forces."""
    res = Results(out)
    try:
        summary = res.summary
        ds = res.dataset
        expect = [peak_force(k, m) for m in MASSES]
        np.testing.assert_allclose(summary["peak_force.spring"], expect, rtol=RTOL)
        np.testing.assert_array_equal(summary["peak_force.spring"], ds["peak_force"].values[:, 0])
        assert list(summary["status"]) == ["ok"] * len(MASSES)
    finally:
        res.close()


# ------------------------------------------------------------------------------------------------
# item 8: prescribed motion on a node held by a rigid wall
# ------------------------------------------------------------------------------------------------

DRIVEN_INTO_WALL = """\
name: driven
curves:
  push: {x: [0.0, 1.0], y: [-2.0, -2.0]}
nodes:
  anchor: {position: [0.0], fixed: true}
  body:   {position: [0.1], mass: 1.0}
springs:
  spring:
    nodes: [anchor, body]
    material: {type: linear_elastic, stiffness: 1.0e4}
prescribed_motion:
  - {node: body, quantity: velocity, direction: x, curve: push}
rigid_walls:
  - {id: stop, point: [0.05], normal: [1.0]WALL_NODES}
end_time: 0.05
output: {histories: none}
"""


@pytest.mark.parametrize(
    "nodes, line, field",
    [(", nodes: [anchor, body]", 14, "rigid_walls.0.nodes.1"), ("", 14, "rigid_walls.0")],
)
def test_a_wall_holding_a_node_with_prescribed_motion_into_it_is_refused(
    tmp_path: Path, cli: Cli, nodes: str, line: int, field: str
) -> None:
    model = tmp_path / "m.yaml"
    model.write_text(DRIVEN_INTO_WALL.replace("WALL_NODES", nodes))
    for cmd in (("validate", model), ("simulate", model, "-o", tmp_path / "out")):
        p = cli(*cmd)
        assert_exit_2(p, f"m.yaml:{line}: {field}:", "'body'", "'stop'", "prescribed_motion.0")
    assert not (tmp_path / "out" / "results.nc").exists()


def test_a_floor_holding_a_node_driven_along_it_is_allowed_and_follows_the_motion(tmp_path: Path) -> None:
    """2-D: the floor's normal (y) is across the driven direction (x): no conflict. The node follows
    x = 0.3 + 2 t exactly and never goes below the floor (gravity pulls it onto it)."""
    from helpers import run_model

    model = {
        "name": "slide",
        "curves": {"speed": {"x": [0.0, 1.0], "y": [2.0, 2.0]}},
        "nodes": {"sled": {"position": [0.3, 0.0], "mass": 1.0}},
        "gravity": [0.0, -9.81],
        "prescribed_motion": [{"node": "sled", "quantity": "velocity", "direction": "x", "curve": "speed"}],
        "rigid_walls": [{"id": "floor", "point": [0.0, 0.0], "normal": [0.0, 1.0]}],
        "end_time": 0.1,
        "time_step": {"dt": 1.0e-4},
        "output": {"interval": 1.0e-3, "histories": ["position"]},
    }
    out, _, plan = run_model(model)
    pos = out.histories["position"]  # (time, node, axis, variant)
    t = plan.times
    np.testing.assert_allclose(pos[:, 0, 0, 0], 0.3 + 2.0 * t, rtol=0, atol=1e-9)
    assert pos[:, 0, 1, 0].min() >= -1e-12


# ------------------------------------------------------------------------------------------------
# item 9: a kill between the final renames
# ------------------------------------------------------------------------------------------------


def _kill_after(monkeypatch: pytest.MonkeyPatch, n: int) -> list[tuple[str, str]]:
    """Make ``os.replace`` raise (as a kill would stop the process) after ``n`` successful calls."""
    done: list[tuple[str, str]] = []
    real = os.replace

    def replace(a: Any, b: Any) -> None:
        if len(done) >= n:
            raise OSError("simulated kill between renames")
        real(a, b)
        done.append((str(a), str(b)))

    monkeypatch.setattr(os, "replace", replace)
    return done


def test_a_kill_after_the_first_rename_of_a_rerun_leaves_a_folder_results_refuses(
    tmp_path: Path, cli: Cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    study = write(tmp_path)
    out = tmp_path / "out"
    runner.run_study(study, out)
    assert_analytic(out)
    (tmp_path / "model.yaml").write_text(TINY_MODEL.replace(f"stiffness: {K}", f"stiffness: {2 * K}"))
    with monkeypatch.context() as mp:
        _kill_after(mp, 1)
        with pytest.raises(OSError, match="simulated kill"):
            runner.run_study(study, out)
    with pytest.raises(InputError, match="the result folder is inconsistent: re-run with --force"):
        Results(out)
    assert_exit_2(cli("summary", out), "the result folder is inconsistent: re-run with --force")
    p = cli("run", study, "-o", out, "--force", "--progress", "off")
    assert p.returncode == 0, p.stderr
    assert_analytic(out, 2 * K)


@pytest.mark.parametrize("n", [0, 1, 2, 3, 4])
def test_a_kill_at_any_rename_leaves_old_results_or_a_refused_folder_never_a_mixed_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, n: int
) -> None:
    study = write(tmp_path)
    out = tmp_path / "out"
    runner.run_study(study, out)
    (tmp_path / "model.yaml").write_text(TINY_MODEL.replace(f"stiffness: {K}", f"stiffness: {2 * K}"))
    with monkeypatch.context() as mp:
        done = _kill_after(mp, n)
        try:
            runner.run_study(study, out)
            killed = False
        except OSError:
            killed = True
    try:
        res = Results(out)
    except InputError as exc:
        assert killed and "the result folder is inconsistent" in str(exc), (done, str(exc))
        return
    res.close()
    # whatever opens is one run's results: the old (stiffness K) or, with every rename done, the new
    assert_analytic(out, 2 * K if not killed else K)


# ------------------------------------------------------------------------------------------------
# item 12: completion mark and checksums
# ------------------------------------------------------------------------------------------------


STORES = {"netcdf": ("results.nc", "results.nc.partial"), "zarr": ("results.zarr", "results.zarr.partial")}


def _interrupted(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, chunks: int, store: str = "netcdf"
) -> tuple[Path, Path]:
    """A run of TINY_STUDY (one variant a chunk) stopped after ``chunks`` chunks: (study, out)."""
    study = write(tmp_path)
    out = tmp_path / "out"
    real = runner.run_chunk
    calls: list[int] = []

    def stop_after(*args: Any) -> Any:
        if len(calls) >= chunks:
            raise KeyboardInterrupt
        calls.append(1)
        return real(*args)

    with monkeypatch.context() as mp:
        mp.setattr(runner, "run_chunk", stop_after)
        with pytest.raises(KeyboardInterrupt):
            runner.run_plan(load_study(study), out, chunk=1, progress=False, store=store)
    assert (out / STORES[store][1]).exists()
    return study, out


def test_a_partial_renamed_by_hand_is_not_a_finished_result(
    tmp_path: Path, cli: Cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    study, out = _interrupted(tmp_path, monkeypatch, 1)
    os.rename(out / "results.nc.partial", out / "results.nc")
    with pytest.raises(InputError, match="not a finished result"):
        Results(out)
    assert_exit_2(cli("summary", out), "not a finished result")
    # a re-run does not reuse the variant of the unfinished file: all three computed, all analytic
    report = runner.run_plan(load_study(study), out, progress=False)
    assert (report.n_reused, report.n_computed) == (0, 3)
    assert_analytic(out)


@pytest.mark.parametrize("store", list(STORES))
def test_a_corrupted_number_in_a_partial_is_computed_again_on_resume(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, store: str
) -> None:
    study, out = _interrupted(tmp_path, monkeypatch, 2, store)
    with open_store(out / STORES[store][1], "a") as nc:
        assert np.ma.filled(nc.variables["done"][:], 0).tolist() == [1, 1, 0]
        good = float(nc.variables["peak_force"][1, 0])
        nc.variables["peak_force"][0, 0] = 1.0e9  # a changed float in the first variant
    report = runner.run_plan(load_study(study), out, resume=True, progress=False)
    assert report.n_computed == 2  # the corrupted variant and the one never done
    assert_analytic(out)
    with open_store(out / STORES[store][0]) as nc:
        assert float(nc.variables["peak_force"][1, 0]) == good  # the intact variant was kept, not recomputed
        assert int(nc.getncattr("complete")) == 1


@pytest.mark.parametrize("store", list(STORES))
def test_a_rerun_does_not_reuse_a_variant_whose_stored_numbers_changed(tmp_path: Path, store: str) -> None:
    study = write(tmp_path)
    out = tmp_path / "out"
    runner.run_plan(load_study(study), out, progress=False, store=store)
    with open_store(out / STORES[store][0], "a") as nc:
        nc.variables["peak_force"][2, 0] = 1.0e9  # damaged after the run finished
    report = runner.run_plan(load_study(study), out, progress=False)  # the folder's kind of store is kept
    assert (out / STORES[store][0]).exists()
    assert (report.n_reused, report.n_computed) == (2, 1)
    assert_analytic(out)


# ------------------------------------------------------------------------------------------------
# item 10: one run at a time in a folder
# ------------------------------------------------------------------------------------------------

HELD_RUN = """\
import sys, time
from pathlib import Path
import crashstudy.run.runner as r
from crashstudy.study.plan import load_study
study, out, started, go = sys.argv[1:5]
real = r.run_chunk
def held(*args):
    res = real(*args)
    Path(started).touch()
    while not Path(go).exists():
        time.sleep(0.05)
    return res
r.run_chunk = held
print(r.run_plan(load_study(study), out, chunk=1, progress=False).n_computed)
"""


def test_a_second_run_into_a_folder_a_live_run_writes_exits_2_and_leaves_it_alone(
    tmp_path: Path, cli: Cli
) -> None:
    study = write(tmp_path)
    out, started, go = tmp_path / "out", tmp_path / "started", tmp_path / "go"
    first = subprocess.Popen(
        [sys.executable, "-c", HELD_RUN, str(study), str(out), str(started), str(go)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 300
        while not started.exists():
            assert first.poll() is None, first.communicate()
            assert time.monotonic() < deadline, "the first run never started a chunk"
            time.sleep(0.05)
        for option in ("--force", "--resume"):
            p = cli("run", study, "-o", out, option, "--progress", "off")
            assert_exit_2(p, f"another crashstudy run is writing {out} (pid {first.pid})")
        assert (out / "results.nc.partial").exists()
        go.touch()
        stdout, stderr = first.communicate(timeout=300)
    finally:
        go.touch()
        if first.poll() is None:
            first.kill()
            first.wait()
    assert first.returncode == 0, stderr
    assert stdout.strip() == "3"
    assert_analytic(out)
    assert not (out / ".crashstudy.lock").exists()  # released and removed with the run
    assert cli("run", study, "-o", out, "--force", "--progress", "off").returncode == 0  # free again


# ------------------------------------------------------------------------------------------------
# item 18: pool workers die with the main process
# ------------------------------------------------------------------------------------------------

POOL_PARENT = """\
import time
from crashstudy.run.backends import make_backend
pool = make_backend(jobs=2)
for _ in pool.imap_unordered(time.sleep, [(600.0,), (600.0,), (600.0,)]):
    pass
"""


def _alive(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def test_pool_workers_exit_when_the_main_process_is_killed() -> None:
    parent = subprocess.Popen([sys.executable, "-c", POOL_PARENT], stderr=subprocess.DEVNULL)
    workers: list[psutil.Process] = []
    try:
        deadline = time.monotonic() + 120
        while len(workers) < 2:
            assert parent.poll() is None
            assert time.monotonic() < deadline, "the pool never started two workers"
            time.sleep(0.1)
            workers = [
                k
                for k in psutil.Process(parent.pid).children()
                if "spawn_main" in " ".join(k.cmdline()) and "resource_tracker" not in " ".join(k.cmdline())
            ]
        time.sleep(1.0)  # let the workers take their tasks (a 600 s sleep each)
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 30  # far below the 600 s the tasks would keep them alive
        while any(_alive(w.pid) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not [w.pid for w in workers if _alive(w.pid)], "pool workers outlived the main process"
    finally:
        for w in workers:
            if _alive(w.pid):
                w.kill()
        if parent.poll() is None:
            parent.kill()


WATCHED_CHILD = """\
import os, sys, time
sys.platform = "darwin"  # no PR_SET_PDEATHSIG: the watchdog thread must do it
from crashstudy.run.backends import _die_with_parent
_die_with_parent(os.getppid())
print(os.getpid(), flush=True)
time.sleep(600)
"""
MIDDLE = f"""\
import subprocess, sys, time
child = subprocess.Popen([sys.executable, "-c", {WATCHED_CHILD!r}], stdout=subprocess.PIPE, text=True)
print(child.stdout.readline().strip(), flush=True)
time.sleep(600)
"""


def test_without_pdeathsig_the_watchdog_ends_a_worker_whose_parent_died() -> None:
    middle = subprocess.Popen([sys.executable, "-c", MIDDLE], stdout=subprocess.PIPE, text=True)
    child = 0
    try:
        assert middle.stdout is not None
        child = int(middle.stdout.readline())
        assert _alive(child)
        middle.send_signal(signal.SIGKILL)
        middle.wait()
        deadline = time.monotonic() + 30  # the watchdog polls twice a second; the child would sleep 600 s
        while _alive(child) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _alive(child), "the watched child outlived its parent"
    finally:
        if child and _alive(child):
            os.kill(child, signal.SIGKILL)
        if middle.poll() is None:
            middle.kill()


def test_variant_checksums_equal_their_definition_in_python_integers() -> None:
    """integrity.variant_sums (column by column for narrow arrays, einsum for wide ones) against its
    definition: per variant, the sum of every 8-byte word (zero-padded per array) times the odd weight
    (2 k + 1) * 0x9E3779B97F4A7C15 of its running index k, modulo 2^64, in Python integers."""
    from crashstudy.results import integrity

    rng = np.random.default_rng(5)
    arrays = {
        "a": rng.normal(size=(9, 3)),
        "b": rng.integers(0, 2**62, (9, 20)).astype(np.uint64),
        "c": rng.integers(-100, 100, (9, 3)).astype("i1"),
        "d": rng.normal(size=9),
    }
    names = sorted(arrays)
    got = integrity.variant_sums(arrays, names)
    for v in range(9):
        raw = b"".join(
            np.ascontiguousarray(arrays[n][v]).tobytes().ljust(-(-arrays[n][v].nbytes // 8) * 8, b"\0")
            for n in names
        )
        words = [int.from_bytes(raw[8 * k : 8 * k + 8], "little") for k in range(len(raw) // 8)]
        truth = sum(w * (2 * k + 1) * 0x9E3779B97F4A7C15 for k, w in enumerate(words)) % 2**64
        assert int(got[v]) == truth, v
