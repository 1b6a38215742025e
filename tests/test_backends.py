"""Every execution backend gives results identical to the in-process run.

One suite (:class:`BackendSuite`) is inherited by each backend: in-process, a process pool of two
workers (``--jobs 2``) and a Dask ``LocalCluster`` of two worker processes on loopback (the one
``DaskBackend("local")`` starts, shared by the module's tests that are not about starting a cluster,
which reach it by its address as ``--scheduler tcp://127.0.0.1:PORT``). Each runs the same small study (a 1-D crush spring and a body spring, 4 x 5
variants over body mass and impact speed, every history kept) and must reproduce the in-process
``results.nc`` exactly, variable by variable (NaN where the reference has NaN): with the default
chunking, with many small chunks, and when a run is interrupted after two chunks and resumed.
Dask-specific tests: a worker process dying mid-task (on the module's cluster, whose nanny replaces it),
a missing ``distributed`` install, an unreachable scheduler, and the real command line with
``--scheduler local``.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import pickle
import sys
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import pytest
import xarray as xr

import crashstudy.run.backends
from crashstudy.errors import InputError
from crashstudy.results import integrity, regions
from crashstudy.results.chunk_result import ChunkResult
from crashstudy.results.store import PARTIAL, ResultWriter
from crashstudy.run.dask_backend import DaskBackend
from crashstudy.run.runner import run_chunk, run_plan
from crashstudy.study.plan import load_study
from helpers import on_shared_pool

MODEL = """\
name: two-spring-crush
description: 1-D frontal impact on a crush spring, a body mass behind it on a linear spring.
units: SI
curves:
  crush-loading: {x: [-0.2, -0.02, 0.0], y: [-60000.0, -40000.0, 0.0]}
nodes:
  wall:  {position: [0.0], fixed: true}
  front: {position: [0.3], mass: 50.0}
  body:  {position: [0.9], mass: 800.0}
springs:
  crush:
    nodes: [wall, front]
    material: {type: crush, loading: crush-loading, unloading_stiffness: 5.0e6}
  body:
    nodes: [front, body]
    material: {type: linear_elastic, stiffness: 2.0e6}
initial_velocity: {front: [-10.0], body: [-10.0]}
end_time: 0.02
output: {interval: 1.0e-4, histories: all}
"""

STUDY = """\
name: backend-check
model: model.yaml
matrix:
  nodes.body.mass: [600.0, 800.0, 1000.0, 1200.0]
  impact_velocity: [4.0, 6.0, 8.0, 10.0, 12.0]
"""
N_VARIANTS = 20
SMALL_CHUNK = 3  # 7 chunks of the 20 variants


@pytest.fixture(scope="module")
def study_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("study")
    (d / "model.yaml").write_text(MODEL)
    (d / "study.yaml").write_text(STUDY)
    return d / "study.yaml"


def _load(out: Path) -> xr.Dataset:
    if (out / "results.zarr").is_dir():  # --store zarr: as xarray reads it, less the writer's own bookkeeping
        with xr.open_dataset(out / "results.zarr", engine="zarr", consolidated=False) as ds:
            ds.attrs.pop("crashstudy_dims", None)
            return ds.load()
    with xr.open_dataset(out / "results.nc") as ds:
        return ds.load()


@pytest.fixture(scope="module")
def reference(study_file: Path, tmp_path_factory: pytest.TempPathFactory) -> xr.Dataset:
    """The in-process result, the truth every backend must reproduce."""
    out = tmp_path_factory.mktemp("reference")
    rep = run_plan(load_study(study_file), out, force=True, progress=False)
    assert rep.n_failed == 0 and rep.n_computed == N_VARIANTS
    return _load(out)


@pytest.fixture(scope="module")
def local_cluster() -> Iterator[DaskBackend]:
    """One ``--scheduler local`` cluster (``DaskBackend("local")``: 2 worker processes of one thread on
    loopback) for the module's tests that are not about starting a cluster (a worker that dies in a test is
    replaced by its nanny); they reach it by
    its address (``--scheduler tcp://127.0.0.1:PORT``). Each start costs ~2 worker processes importing
    numpy, numba and crashstudy and loading the kernel: once here instead of once per run."""
    backend = DaskBackend("local")
    yield backend
    backend.close()


def assert_same_results(ds: xr.Dataset, ref: xr.Dataset) -> None:
    """Every variable, coordinate and attribute equal, bit for bit (NaN where the reference has NaN)."""
    assert set(ds.data_vars) == set(ref.data_vars)
    xr.testing.assert_identical(ds, ref)


class InterruptAfter:
    """A backend wrapper that raises KeyboardInterrupt once ``n`` chunk results have been handed out."""

    def __init__(self, inner: crashstudy.run.backends.Backend, n: int) -> None:
        self.inner, self.n = inner, n

    def imap_unordered(self, fn: Callable[..., Any], tasks: Iterable[tuple[Any, ...]]) -> Iterator[Any]:
        for k, res in enumerate(self.inner.imap_unordered(fn, tasks)):
            if k == self.n:
                raise KeyboardInterrupt
            yield res

    def close(self) -> None:
        self.inner.close()


class BackendSuite:
    """Tests run for every backend; subclasses set ``options`` (keyword arguments of ``run_plan``)."""

    options: dict[str, Any] = {}
    partial, final = PARTIAL, "results.nc"  # the store's names (results.zarr[.partial] with store="zarr")
    shared_cluster = False  # True: ``scheduler`` is the address of the module's LocalCluster (local_cluster)

    @pytest.fixture(autouse=True)
    def _scheduler(self, request: pytest.FixtureRequest) -> None:
        if self.shared_cluster:
            address = request.getfixturevalue("local_cluster").cluster.scheduler_address
            self.options = {**type(self).options, "scheduler": address}

    def run(self, study_file: Path, out: Path, **kw: Any) -> Any:
        return run_plan(
            load_study(study_file),
            out,
            force=not kw.get("resume", False),
            progress=False,
            **self.options,
            **kw,
        )

    def test_results_identical_to_in_process(
        self, study_file: Path, reference: xr.Dataset, tmp_path: Path
    ) -> None:
        rep = self.run(study_file, tmp_path)
        assert (rep.n_variants, rep.n_computed, rep.n_failed) == (N_VARIANTS, N_VARIANTS, 0)
        assert_same_results(_load(tmp_path), reference)

    def test_many_small_chunks_identical_to_in_process(
        self, study_file: Path, reference: xr.Dataset, tmp_path: Path
    ) -> None:
        rep = self.run(study_file, tmp_path, chunk=SMALL_CHUNK)
        assert rep.n_computed == N_VARIANTS
        assert_same_results(_load(tmp_path), reference)

    def test_interrupted_run_resumes_to_identical_results(
        self, study_file: Path, reference: xr.Dataset, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        real = crashstudy.run.backends.make_backend
        with monkeypatch.context() as m:
            m.setattr(
                crashstudy.run.backends, "make_backend", lambda *a, **k: InterruptAfter(real(*a, **k), 2)
            )
            with pytest.raises(KeyboardInterrupt):
                self.run(study_file, tmp_path, chunk=SMALL_CHUNK)
        assert (tmp_path / self.partial).exists() and not (tmp_path / self.final).exists()
        rep = self.run(study_file, tmp_path, chunk=SMALL_CHUNK, resume=True)
        assert rep.n_computed == N_VARIANTS - 2 * SMALL_CHUNK  # only the chunks not yet written
        assert_same_results(_load(tmp_path), reference)


class TestInProcess(BackendSuite):
    options: dict[str, Any] = {}


class TestProcessPool(BackendSuite):
    """``--jobs 2``: every run of the suite on the test process's shared pool of 2 worker processes
    (helpers.shared_process_pool: what they test is the numbers the workers compute, not the pool's start;
    4 runs started 8 worker processes, the pool is shared with test_design's --jobs 2 run too)."""

    options = {"jobs": 2}

    @pytest.fixture(autouse=True)
    def _shared_pool(self, monkeypatch: pytest.MonkeyPatch) -> None:
        on_shared_pool(monkeypatch)


class TestInProcessZarr(BackendSuite):
    """``--store zarr``: the same numbers (issue 19 item 2)."""

    options = {"store": "zarr"}
    partial, final = "results.zarr.partial", "results.zarr"


#: libraries a task does not use: the writer's and reader's, and the input validation's (pydantic)
NOT_FOR_A_TASK = (
    "distributed",
    "matplotlib",
    "netCDF4",
    "pandas",
    "pyarrow",
    "pydantic",
    "scipy",
    "xarray",
    "zarr",
)


def test_pool_worker_task_imports_neither_writer_nor_reader(study_file: Path, tmp_path: Path) -> None:
    """What a ``--jobs`` worker unpickles for a task (``run_chunk`` and the plan, as ``ProcessPool``
    sends them) imports none of the writer's, reader's or validation's libraries: a fresh interpreter
    loads the task and lists the top-level packages in its ``sys.modules`` (each worker paid ~1 s CPU
    for them)."""
    import subprocess

    task = tmp_path / "task.pkl"
    task.write_bytes(pickle.dumps((run_chunk, (load_study(study_file), 0, 2, "compiled"))))
    code = (
        "import pickle, sys; fn, args = pickle.loads(open(sys.argv[1], 'rb').read()); "
        "print(fn.__module__, sorted({m.partition('.')[0] for m in sys.modules}))"
    )
    proc = subprocess.run([sys.executable, "-c", code, str(task)], capture_output=True, text=True, check=True)
    module, loaded = proc.stdout.split(" ", 1)
    assert module == "crashstudy.run.chunk"  # (runner re-exports it)
    assert "numpy" in loaded and "crashstudy" in loaded  # the listing is of the task's own imports
    assert [name for name in NOT_FOR_A_TASK if repr(name) in loaded] == []


# --- Dask only ------------------------------------------------------------------------------------


def _die_once(marker: str, fn: Callable[..., Any], *args: Any) -> Any:
    """Kill this worker process in the first task that runs (atomically claimed by creating ``marker``).
    A task that writes a region of a Zarr store (``fn`` = ``regions.write_region`` with its store path)
    first writes half of its region with wrong values: the worker dies with the region half written."""
    try:
        os.close(os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return fn(*args)
    if getattr(fn, "func", None) is regions.write_region:
        from crashstudy.results.zarr_file import ZarrFile

        nc = ZarrFile(fn.args[1], "a")
        lo, hi = args[1][0]
        for name in integrity.checked_names(nc)[:3]:
            nc.variables[name][lo:hi] = 1  # wrong values in the first variables; the others never written
    os._exit(1)  # the worker dies mid-task, as if killed; its nanny starts a new one


class KillOneWorker:
    """Wraps a backend so that the worker running the first task dies in it; records what each task
    sends back to the client (the result and its size pickled, as Dask sends it)."""

    def __init__(self, inner: crashstudy.run.backends.Backend, marker: Path) -> None:
        self.inner, self.marker = inner, str(marker)
        self.received: list[tuple[Any, int]] = []

    def imap_unordered(self, fn: Callable[..., Any], tasks: Iterable[tuple[Any, ...]]) -> Iterator[Any]:
        for res in self.inner.imap_unordered(functools.partial(_die_once, self.marker, fn), tasks):
            self.received.append((res, len(pickle.dumps(res, protocol=5))))
            yield res

    def close(self) -> None:
        self.inner.close()


def receipt_bound(variants: int) -> int:
    """Bytes a region's receipt may take: its checksums and a little more, not the arrays."""
    return 64 * variants + 16 * 1024


def test_receipt_is_checksums_and_texts_not_arrays(
    study_file: Path, reference: xr.Dataset, tmp_path: Path
) -> None:
    """In this process: a region written by ``write_region`` and recorded from its receipt equals the
    in-process result; its receipt is under 64 B per variant + 16 KiB, the chunk's arrays 32.6 kB per
    variant; a task of another study writes nothing; a receipt whose checksums the store does not hold (a folder the client does not see) is an
    input error naming -o."""
    plan = load_study(study_file)
    writer = ResultWriter(tmp_path, plan, store="zarr", chunk=8)
    fn, tasks = regions.region_tasks(writer, run_chunk, plan, [(0, N_VARIANTS)], "compiled")
    receipts = [fn(*t) for t in tasks]
    assert [r.ranges for r in receipts] == [((0, 8),), ((8, 16),), ((16, 20),)]
    arrays = len(pickle.dumps(run_chunk(plan, 0, 8), protocol=5))
    for r in receipts:
        assert len(pickle.dumps(r, protocol=5)) < receipt_bound(r.size) < arrays
    other = study_file.with_name("other-study.yaml")
    other.write_text(STUDY.replace("1200.0]", "1300.0]"))
    with pytest.raises(OSError, match="no longer the store of this task's study"):
        fn(load_study(other), [(0, 8)], "compiled")  # a task left over from a run of another study
    bad = dataclasses.replace(receipts[0], sums=receipts[0].sums + 1)
    with pytest.raises(InputError) as exc:
        writer.write(bad)
    assert exc.value.problems[0].file == "-o" and "every worker sees" in exc.value.problems[0].message
    for r in reversed(receipts):  # in any order: the text codes are the store's
        writer.write(r)
    writer.finish()
    assert_same_results(_load(tmp_path), reference)


def test_regions_are_cut_at_stored_chunks() -> None:
    assert list(regions.regions([(0, 3), (4, 11), (13, 14)], 5)) == [
        [(0, 3), (4, 5)],
        [(5, 10)],
        [(10, 11), (13, 14)],
    ]


@pytest.mark.parametrize("kill_at", [1, 2, 3])
def test_zarr_store_replaced_whole_at_every_rename(
    study_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, kill_at: int
) -> None:
    """A re-run that replaces a finished results.zarr is killed at its k-th rename: results.zarr is
    still a whole, finished store (the old one or the new one), never missing."""
    plan = load_study(study_file)
    run_plan(plan, tmp_path, force=True, progress=False, store="zarr")
    real, calls = os.replace, []

    def dying(a: Any, b: Any) -> None:
        if Path(a).parent == tmp_path:  # the folder's entries (not the files zarr writes inside a store)
            calls.append(a)
        if len(calls) == kill_at and Path(a).parent == tmp_path:
            raise KeyboardInterrupt  # as if killed before this rename
        real(a, b)

    monkeypatch.setattr(os, "replace", dying)
    with pytest.raises(KeyboardInterrupt):
        run_plan(plan, tmp_path, progress=False, store="zarr")  # a re-run: the old store is replaced
    monkeypatch.setattr(os, "replace", real)
    with integrity.open_store(tmp_path / "results.zarr") as nc:
        assert int(nc.getncattr("complete")) == 1
        assert integrity.intact(nc, nc.variables["done"][:] == 1).all()


def test_dask_backend_without_distributed_asks_for_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # `import distributed` now raises ImportError
    with pytest.raises(InputError) as exc:
        DaskBackend("local")
    assert [(p.file, p.message) for p in exc.value.problems] == [
        ("--scheduler", "the Dask backend needs the optional extra: pip install 'crashstudy[dask]'")
    ]
    with pytest.raises(InputError, match=r"crashstudy\[dask\]"):
        crashstudy.run.backends.make_backend(1, "tcp://127.0.0.1:8786")


def test_cli_without_distributed_exits_2_with_the_install_hint(
    study_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from crashstudy.cli.main import main

    monkeypatch.setitem(sys.modules, "distributed", None)
    code = main(
        ["run", str(study_file), "--scheduler", "local", "-o", str(tmp_path / "out"), "--progress", "off"]
    )
    assert code == 2
    assert "pip install 'crashstudy[dask]'" in capsys.readouterr().err


def test_backend_that_cannot_start_leaves_no_partial_result(
    study_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(InputError):
        run_plan(load_study(study_file), tmp_path, scheduler="local", force=True, progress=False)
    assert not (tmp_path / PARTIAL).exists()


def test_unreachable_scheduler_is_an_input_error_naming_the_address() -> None:
    with pytest.raises(InputError, match=r"cannot connect to a Dask scheduler at 'tcp://127\.0\.0\.1:9'"):
        DaskBackend("tcp://127.0.0.1:9", timeout=2)  # port 9 (discard): nothing listens on loopback


def test_cli_run_with_local_scheduler_exits_0(
    study_file: Path, reference: xr.Dataset, tmp_path: Path, cli: Any
) -> None:
    out = tmp_path / "cli-out"
    proc = cli("run", str(study_file), "--scheduler", "local", "-o", str(out), "--progress", "off")
    assert proc.returncode == 0, proc.stderr
    assert f"{N_VARIANTS} variants" in proc.stdout
    assert_same_results(_load(out), reference)


# --- on the module's LocalCluster (local_cluster), last: the cluster lives only while these tests run ----


@pytest.mark.parametrize("store", ["netcdf", "zarr"])
def test_dask_study_completes_identically_when_a_worker_dies(
    study_file: Path,
    reference: xr.Dataset,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    store: str,
    local_cluster: DaskBackend,
) -> None:
    """A worker of the module's LocalCluster dies in its first task (with Zarr: its region half written): the
    result is the in-process one. With Zarr the workers write the store and send back only receipts (issue
    19 item 3). The cluster's nanny starts a new worker; the test waits for it, so that the cluster has its
    2 workers again for the tests after it (the dead worker's replacement is the only process it starts)."""
    marker = tmp_path / "worker-killed"
    real = crashstudy.run.backends.make_backend
    made: list[KillOneWorker] = []
    monkeypatch.setattr(
        crashstudy.run.backends,
        "make_backend",
        lambda *a, **k: made.append(KillOneWorker(real(*a, **k), marker)) or made[-1],
    )
    out = tmp_path / "out"
    rep = run_plan(
        load_study(study_file),
        out,
        scheduler=local_cluster.cluster.scheduler_address,
        chunk=SMALL_CHUNK,
        force=True,
        progress=False,
        store=store,
    )
    assert marker.exists(), "no worker was killed"
    local_cluster.client.wait_for_workers(2, timeout=120)
    assert rep.n_computed == N_VARIANTS and rep.n_failed == 0
    assert_same_results(_load(out), reference)
    received = made[0].received
    assert sum(r.size for r, _ in received) == N_VARIANTS
    if store == "zarr":
        assert all(isinstance(r, regions.Receipt) for r, _ in received)
        assert all(n < receipt_bound(r.size) for r, n in received), [n for _, n in received]
    else:  # the client writes: every array comes back
        assert all(isinstance(r, ChunkResult) for r, _ in received)


class TestDaskLocalCluster(BackendSuite):
    """The module's LocalCluster, by its address (an interrupted run closes only its client: the tasks
    the workers had started finish on them, as on a cluster the user started)."""

    shared_cluster = True


class TestDaskLocalClusterZarr(TestInProcessZarr):
    """The module's LocalCluster by its address; the workers write the store."""

    shared_cluster = True


def test_dask_local_workers_run_the_kernel_with_one_thread_each(local_cluster: DaskBackend) -> None:
    """``DaskBackend("local")`` (the module's): 2 workers of one thread; each task's kernel runs with one."""
    from crashstudy.kernel.compiled import get_threads

    assert local_cluster.worker_threads() == 2
    assert sorted(local_cluster.imap_unordered(get_threads, [()] * 6)) == [1] * 6
