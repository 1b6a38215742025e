"""Ctrl-C during the first chunk of a run (issue 13, item 4), with real processes.

A new user pressed Ctrl-C while a kernel compiled in the first chunk: it was ignored until the compile
and the chunk had finished (~30 s). The runs here start from empty caches (a fresh
``CRASHSTUDY_KERNEL_CACHE`` and ``NUMBA_CACHE_DIR`` in ``tmp_path``) and without background compiles
(``CRASHSTUDY_BACKGROUND_COMPILE=0``), so a study big enough for the generic kernel to pay compiles it
in the first chunk. The signal is sent once the progress line says the run has started its chunks.

What proves that the signal was acted on during the compile, without timing it: the interrupted run
exits 130, its partial file holds no finished variant (the compile of the generic kernel and the first
chunk after it would have finished first), the generic kernel is not in the fresh numba cache (the
compile was stopped) and no compile is left running (the kernel cache's compile lock is free). The
seconds from signal to exit are printed (``pytest -s``), never asserted.

``--resume`` (in this process) then computes every variant; its values are checked against a fresh computation of them
run in this process on a few variants (the kernels agree bitwise, docs/kernels.md; tolerance rtol 1e-12).
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import xarray as xr

from crashstudy.run.runner import run_chunk
from crashstudy.study.plan import load_study
from helpers import run_cli

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "studies" / "models" / "frontal-9mass.yaml"

# 10 x 10 x 30 variants of the frontal model: ~30 s on the NumPy reference, so the run compiles this
# shape's generated kernel first (~11 s, the note says so) and then runs it
BIG = """\
name: frontal-3000
model: {model}
matrix:
  nodes.engine.mass: [120.0, 130.0, 140.0, 150.0, 160.0, 170.0, 180.0, 190.0, 200.0, 210.0]
  curves.rail-loading.scale: [0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6]
  impact_velocity: [{speeds}]
"""
# the example study cut to its first 40 ms (1000 variants, histories none: one chunk): the reference runs it
# (~7 s: quicker than compiling a kernel first; the whole 0.12 s, ~21 s, would compile the generated kernel)
SMALL = """\
name: frontal-1000
model: {model}
matrix:
  nodes.engine.mass: [120.0, 130.0, 140.0, 150.0, 160.0, 170.0, 180.0, 190.0, 200.0, 210.0]
  curves.rail-loading.scale: [0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6]
  impact_velocity: [{speeds}]
set: {{end_time: 0.04, output: {{histories: none}}}}
"""


def _study(tmp_path: Path, template: str, n_speeds: int) -> Path:
    speeds = ", ".join(f"{v:.4f}" for v in np.linspace(10.0, 20.0, n_speeds))
    path = tmp_path / "study.yaml"
    path.write_text(template.format(model=MODEL, speeds=speeds))
    return path


def _fresh_env(tmp_path: Path) -> dict[str, str]:
    return dict(
        os.environ,
        CRASHSTUDY_KERNEL_CACHE=str(tmp_path / "kernels"),
        NUMBA_CACHE_DIR=str(tmp_path / "numba"),
        CRASHSTUDY_BACKGROUND_COMPILE="0",
        CRASHSTUDY_KERNEL="",
    )


def _default_sigint() -> None:
    """In the child: SIGINT handled as in a terminal (a background test run inherits it ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _cli(*args: str | Path) -> list[str]:
    return [sys.executable, "-m", "crashstudy.cli", *map(str, args)]


def _interrupt_when_started(
    study: Path, out: Path, env: dict[str, str], wait: float, started: str = r"\b0/\d+ variants"
) -> tuple[int, str]:
    """Start ``crashstudy run``, send SIGINT ``wait`` s after its stderr matches ``started`` (default: the
    progress line says ``0/N variants``, the chunks have started), return (exit code, stderr)."""
    err_path = out.parent / "stderr.txt"
    with open(err_path, "w") as err:
        proc = subprocess.Popen(
            _cli("run", study, "-o", out, "--progress", "on"),
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=err,
            preexec_fn=_default_sigint,
        )
        t0 = time.monotonic()
        while not re.search(started, err_path.read_text()):
            if proc.poll() is not None:
                pytest.fail(
                    f"the run ended (exit {proc.returncode}) before it started:\n{err_path.read_text()}"
                )
            if time.monotonic() - t0 > 240:
                proc.kill()
                pytest.fail("the run did not start its chunks within 240 s")
            time.sleep(0.01)
        time.sleep(wait)
        proc.send_signal(signal.SIGINT)
        t_signal = time.monotonic()
        try:
            code = proc.wait(timeout=240)
        except subprocess.TimeoutExpired:
            proc.kill()
            pytest.fail("the run did not stop within 240 s of Ctrl-C")
    print(f"\nexit {code} {time.monotonic() - t_signal:.2f} s after SIGINT")
    return code, err_path.read_text()


def _done(out: Path) -> int:
    with netCDF4.Dataset(out / "results.nc.partial") as nc:
        return int(np.asarray(nc.variables["done"][:], dtype=bool).sum())


def _kernel_in_cache(numba_dir: Path) -> bool:
    """Whether numba's cache holds the index of a compiled kernel (generic or generated; the index is
    written after the compiled code)."""
    return any(
        p.name.startswith("compiled._run") or ".run_blocks-" in p.name for p in numba_dir.rglob("*.nbi")
    )


def _lock_free(kernels: Path) -> bool:
    from crashstudy.kernel.choice import compiling

    return not compiling(kernels)


def _resume_and_check(study: Path, out: Path, n: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--resume`` in this process (on the generic kernel of the test session's cache: the kernel does
    not change the values) computes all ``n`` variants; a few equal a fresh computation of them here."""
    monkeypatch.setenv("CRASHSTUDY_KERNEL", "generic")
    monkeypatch.setenv("CRASHSTUDY_BACKGROUND_COMPILE", "0")
    p = run_cli("run", study, "-o", out, "--resume", "--progress", "off")
    assert p.returncode == 0, p.stderr
    assert f"({n} variants computed" in p.stdout, p.stdout
    assert not (out / "results.nc.partial").exists()
    plan = load_study(study)
    with xr.open_dataset(out / "results.nc") as ds:
        assert ds.sizes["variant"] == n
        assert int(np.count_nonzero(ds["status"].values == 0)) == n  # 0: ok (flag_meanings)
        for lo in (0, n // 2, n - 3):
            ref = run_chunk(
                plan, lo, lo + 3, kernel="generic"
            )  # a fresh computation (bitwise the reference's)
            got = ds["peak_force"].isel(variant=slice(lo, lo + 3)).values
            np.testing.assert_allclose(got, ref.out.peak_force.T, rtol=1e-12, atol=0.0)
            got_a = ds["absorbed_energy"].isel(variant=slice(lo, lo + 3)).values
            np.testing.assert_allclose(got_a, ref.out.absorbed_energy.T, rtol=1e-12, atol=0.0)


def test_ctrl_c_while_the_kernel_compiles_stops_the_compile_at_once(
    tmp_path: Path,
) -> None:
    study = _study(tmp_path, BIG, 30)
    out = tmp_path / "out"
    code, err = _interrupt_when_started(
        study,
        out,
        _fresh_env(tmp_path),
        wait=2.0,
        started=r"note: compiling the generated kernel .*Ctrl-C stops",
    )
    assert code == 130, err
    assert "interrupted" in err and "--resume" in err and "Traceback" not in err, err
    assert sorted(p.name for p in out.iterdir()) == ["results.nc.partial"]
    assert _done(out) == 0  # stopped during the compile, before any chunk
    assert not _kernel_in_cache(tmp_path)  # the compile was stopped, not waited for (numba and kernel caches)
    assert _lock_free(tmp_path / "kernels")  # and no compile is left running
    # (--resume after an interrupted first chunk: the next test; 3000 variants with histories cost ~30 s)


def test_ctrl_c_while_the_reference_runs_the_first_chunk_stops_it_and_resume_computes_every_variant(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    study = _study(tmp_path, SMALL, 10)
    out = tmp_path / "out"
    code, err = _interrupt_when_started(study, out, _fresh_env(tmp_path), wait=0.5)
    assert code == 130, err
    assert sorted(p.name for p in out.iterdir()) == ["results.nc.partial"]
    assert _done(out) == 0  # the reference checks for Ctrl-C every 256 steps, inside the first chunk
    _resume_and_check(study, out, 1000, monkeypatch)
