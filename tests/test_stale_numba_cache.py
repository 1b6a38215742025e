"""numba's disk cache and an edited law in another file (kernel/cache.py: fresh_numba_cache).

numba keys a cached function on its own file's time stamp and bytecode only. A compiled function that
calls a law of another file (step_laws.spring_extremes calls laws.peak, as compiled._run calls every law)
was loaded from the cache with the old law inlined after an edit of laws.py alone: a silently wrong
result in a checkout that changes (git pull, branch switch, editable install). Each case runs a copy of
the package in fresh processes, the only way numba loads from its disk cache."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from helpers import ROOT

# peak force, largest crush, largest elongation of a spring at force -3 N, elongation -0.5 m, after
# (2, 0, 0): a running maximum gives (3, 0.5, 0); the edited law below (the smaller of the two) gives (2, 0, -0.5)
CALL = (
    "from crashstudy.kernel.step_laws import spring_extremes as f\n"
    "print(f(2.0, 0.0, 0.0, -3.0, 1.0, -0.5, 1.0), sum(f.stats.cache_hits.values()))\n"
)


def _run(src: Path, cache: Path) -> tuple[tuple[float, ...], int]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "CRASHSTUDY_"))}
    env.update(PYTHONPATH=str(src), NUMBA_CACHE_DIR=str(cache / "numba"))
    env["CRASHSTUDY_KERNEL_CACHE"] = str(cache / "kernels")
    out = subprocess.run(
        [sys.executable, "-c", CALL],
        env=env,
        cwd=src,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    ).stdout.split(")")
    return tuple(float(v) for v in out[0].strip("( ").split(",")), int(out[1])


def test_an_edited_law_is_compiled_again_into_its_callers_in_other_files(tmp_path: Path) -> None:
    src = tmp_path / "src"
    shutil.copytree(
        ROOT / "src" / "crashstudy", src / "crashstudy", ignore=shutil.ignore_patterns("__pycache__")
    )
    cache = tmp_path / "cache"
    cache.mkdir(mode=0o700)
    assert _run(src, cache) == ((3.0, 0.5, 0.0), 0)  # compiled: nothing in the cache yet
    laws = src / "crashstudy" / "kernel" / "laws.py"
    text = laws.read_text()
    assert "    return x if x > p else p\n" in text
    laws.write_text(text.replace("    return x if x > p else p\n", "    return x if x < p else p\n", 1))
    # step_laws.py unchanged: before the stamp, numba loaded its cached machine code with the old peak
    assert _run(src, cache) == ((2.0, 0.0, -0.5), 0)
    # the same sources again: loaded from the cache, not compiled a third time
    assert _run(src, cache) == ((2.0, 0.0, -0.5), 1)
