"""Comparisons 6-7 of the skipping benchmark, on whole runs: ``run_chunk`` over duplicated variants, and
the numba cache (a first and a second ``crashstudy simulate`` process).

Part of benchmarks/skipping.py (what skipping costs and saves, issue 4, item 3), which describes the
comparisons and how they are timed."""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from crashstudy.run.runner import run_chunk
from crashstudy.study.plan import load_study
from skipping_measure import MODEL, PEAKS, SMALL_MODEL, Case, Row, gain, loadavg, measure


def study_plan(folder: Path, name: str, scales: list[float]) -> Any:
    text = {
        "name": name,
        "model": MODEL.name,
        "set": {"output": {"histories": "none"}},
        "matrix": {
            "nodes.engine.mass": [120.0 + 10 * k for k in range(10)],
            "impact_velocity": [10.0 + 10.0 * k / 9 for k in range(10)],
            "curves.rail-loading.scale": scales,
        },
    }
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(text, sort_keys=False))
    return load_study(path)


def cmp_dedup(n_unique_axis: int, repeats: int, log: list[str]) -> list[Row]:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / MODEL.name).write_text(MODEL.read_text())
        uniq = study_plan(
            folder, "all-unique", [round(float(v), 6) for v in np.linspace(0.7, 1.6, n_unique_axis)]
        )
        dup = study_plan(folder, "hundred-unique", [1.0] * n_unique_axis)
        ref = study_plan(folder, "the-hundred", [1.0])
    n = uniq.n_variants
    cases = [
        Case(f"{n} unique", lambda: run_chunk(uniq, 0, n), lambda: run_chunk(uniq, 0, 16)),
        Case(f"{n} variants, 100 unique", lambda: run_chunk(dup, 0, n), lambda: run_chunk(dup, 0, 16)),
    ]
    before, after = measure(cases, repeats)
    full, once = cases
    ref_out = run_chunk(ref, 0, ref.n_variants).out
    # variant k of the duplicated study is variant k // n_unique_axis of the 100-variant one
    idx = np.arange(n) // n_unique_axis
    exact = all(
        np.array_equal(getattr(once.result.out, a), getattr(ref_out, a)[..., idx])
        for a in (*PEAKS, "absorbed_energy", "t_end", "energy_error")
    )
    log.append(f"6. run_chunk dedup, {n} variants, load {before} -> {after}")
    for c in cases:
        log.append(f"   {c.name}: CPU {c.cpu_med:.3g} s, wall {c.wall_med:.3g} s")
    return [
        Row(
            f"identical variants computed once (run_chunk, {n} variants, 100 unique)",
            f"{full.name}: CPU {full.cpu_med:.3g} s, wall {full.wall_med:.3g} s",
            f"{once.name}: CPU {once.cpu_med:.3g} s, wall {once.wall_med:.3g} s",
            gain(full, once, False),
            f"each variant equals its unique twin run alone: {'exact' if exact else 'DIFFERS'}",
        )
    ]


def run_process(args: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Wall time and CPU time (user + sys of the child) of one process."""
    w0 = time.perf_counter()
    proc = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - w0
    err = proc.stderr.read().decode() if proc.stderr else ""
    if os.waitstatus_to_exitcode(status) != 0:
        raise RuntimeError(f"{' '.join(args)} failed: {err}")
    return wall, usage.ru_utime + usage.ru_stime


def cmp_cache(cold_repeats: int, repeats: int, log: list[str]) -> list[Row]:
    exe = [sys.executable, "-m", "crashstudy.cli", "simulate", str(SMALL_MODEL), "-o"]
    cold: list[tuple[float, float]] = []
    warm: list[tuple[float, float]] = []
    imp: list[tuple[float, float]] = []
    before = loadavg()
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(max(cold_repeats, repeats)):
            env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp) / f"cache{r}"))
            if r < cold_repeats:  # first call: empty cache, the kernel is compiled and cached
                cold.append(run_process([*exe, str(Path(tmp) / f"out{r}a")], env))
            else:
                env["NUMBA_CACHE_DIR"] = str(Path(tmp) / "cache0")
            warm.append(run_process([*exe, str(Path(tmp) / f"out{r}b")], env))  # second call: cache reused
            imp.append(
                run_process([sys.executable, "-c", "import crashstudy.run.runner, crashstudy.cli.main"], env)
            )
    after = loadavg()

    def med(xs: list[tuple[float, float]], k: int) -> float:
        return statistics.median(x[k] for x in xs)

    log.append(f"7. numba cache ({SMALL_MODEL.name}), load {before} -> {after}")
    log.append(
        f"   first call ({len(cold)} runs): wall {[round(x[0], 2) for x in cold]}, CPU {[round(x[1], 2) for x in cold]}"
    )
    log.append(
        f"   second call ({len(warm)} runs): wall {[round(x[0], 2) for x in warm]}, CPU {[round(x[1], 2) for x in warm]}"
    )
    log.append(
        f"   python -c 'import crashstudy.run.runner, crashstudy.cli.main' ({len(imp)} runs): wall median "
        f"{med(imp, 0):.2f} s, CPU {med(imp, 1):.2f} s"
    )
    return [
        Row(
            f"numba cache: second `crashstudy simulate` of {SMALL_MODEL.name} (separate processes)",
            f"first call, empty NUMBA_CACHE_DIR: process wall {med(cold, 0):.1f} s, CPU {med(cold, 1):.1f} s",
            f"second call, cache reused: process wall {med(warm, 0):.2f} s, CPU {med(warm, 1):.2f} s "
            f"(imports alone: wall {med(imp, 0):.2f} s)",
            f"wall {med(cold, 0) / med(warm, 0):.1f}x, CPU {med(cold, 1) / med(warm, 1):.1f}x",
            "both runs exit 0",
        )
    ]
