"""Model-specialised kernels: numba source generated from a batch's topology, compiled once, cached.

The generic kernel (:mod:`crashstudy.kernel.compiled`) reads the topology from arrays at run time:
which nodes a spring joins, its material, how many knots its curves have. Every step it loops over
springs and nodes and keeps a dozen separate block arrays, and LLVM vectorises few of its loops.
Here the topology is written into the source instead, the way a hand-specialised loop would be: one
fused, branch-free pass over the variants of a block per time step computes every spring, every
node update and every summary, with all per-variant numbers (masses, curve knots, stiffnesses,
state, summaries) in rows of ONE block work array ``Z`` with a compile-time row stride, so LLVM can
prove the rows never overlap and puts several variants in one SIMD instruction. Curves that no
study axis changes (and that are equal in every variant of the batch) are read once into local
constants; a spring's 1-D sign that is the same in every variant folds into the operators.

The arithmetic is that of the reference kernel, operation for operation, so results are bitwise
those of :func:`crashstudy.kernel.reference.run_reference` (``tests/test_generated.py``). The
numbers stay per variant: one compiled kernel serves every study of the same model shape.

Scope: every model the schema accepts (1-D and 2-D, every material, gravity, loads, prescribed
motion, rigid walls, early termination); :func:`unsupported` is where a future exception would go. Variants that end (end
time, termination, failure) leave their block once they are an eighth of it ("lane compaction":
their results are written, the running lanes move down), so later steps run over fewer lanes.

Units: whatever consistent system the model uses (the kernel only multiplies and adds; SI in the
examples: m, s, kg, N, J).

Compilation costs seconds per model shape, so the runner uses a generated kernel when the study is
large enough to earn it back, or when this shape's kernel is already compiled (numba's on-disk cache
next to the generated source, in the user's private folder of :mod:`crashstudy.kernel.cache`).
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import re
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

from crashstudy.kernel.cache import cache_dir, checked_dir, why_not_private
from crashstudy.kernel.driver import block_starts, finish, outputs, records, run_blocks
from crashstudy.kernel.gen_constants import _constant_curves, _constants
from crashstudy.kernel.gen_shape import BLOCK, GEN_VERSION, MAX_KNOTS, ROW, _shape, unsupported
from crashstudy.kernel.gen_source import source
from crashstudy.kernel.output import KernelOutput

if TYPE_CHECKING:
    from crashstudy.arrays.batch import Batch

__all__ = [
    "BLOCK",
    "GEN_VERSION",
    "MAX_KNOTS",
    "ROW",
    "_constant_curves",
    "_shape",
    "_source",
    "is_compiled",
    "run_generated",
    "shape_key",
    "unsupported",
]
_LOCK = threading.Lock()
_LOADED: dict[tuple[str, str], Any] = {}  # (kernel folder asked for, shape key) -> module
_source = source


_SOURCES: dict[str, tuple[str, str]] = {}  # repr(shape) -> (source, key)


def _source_key(shape: dict[str, Any]) -> tuple[str, str]:
    """A shape's source and its name (a hash of the source and of the modules it imports), generated once per
    process: the kernel choice, the compile check and the run all ask for it every chunk."""
    r = repr(shape)
    if r not in _SOURCES:
        src = _source(shape)
        imported = tuple(re.findall(r"^from (crashstudy\.[\w.]+) import", src, flags=re.M))
        _SOURCES[r] = (src, hashlib.sha256(src.encode() + laws_fingerprint(imported)).hexdigest()[:20])
    return _SOURCES[r]


@functools.cache
def laws_fingerprint(modules: tuple[str, ...]) -> bytes:
    """A hash of the crashstudy modules a generated kernel imports (its laws and their constants). numba's
    cache checks only the generated file's own time stamp, so a crashstudy whose laws changed while a model's
    source did not would otherwise load the kernel compiled with the old laws; with this in the name, it
    compiles anew."""
    h = hashlib.sha256()
    for name in modules:
        h.update(Path(str(importlib.import_module(name).__file__)).read_bytes())
    return h.digest()


def _module(shape: dict[str, Any]) -> Any:
    """The compiled module for ``shape`` (generated, written and imported once per process and kernel
    folder: a process that changes ``CRASHSTUDY_KERNEL_CACHE`` loads and compiles into the new folder)."""
    src, key = _source_key(shape)
    with _LOCK:
        asked = str(cache_dir())
        loaded = _LOADED.get((asked, key))
        if loaded is not None:
            return loaded
        folder = checked_dir()  # private to this user: numba unpickles what it finds there
        path = folder / f"k_{key}.py"
        if not path.exists() or path.read_text() != src:
            tmp = folder / f".k_{key}.{os.getpid()}.tmp"
            tmp.write_text(src)
            os.replace(tmp, path)
        name = f"crashstudy_generated_{key}"
        spec = importlib.util.spec_from_file_location(name, path)
        assert spec is not None and spec.loader is not None
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
        _LOADED[(asked, key)] = mod
        return mod


def shape_key(shape: dict[str, Any]) -> str:
    """The name of a shape's kernel: a hash of its source."""
    return _source_key(shape)[1]


def is_compiled(
    b: Batch, histories: tuple[str, ...], vary: frozenset[int] | None = None, record: tuple[int, ...] = ()
) -> bool:
    """Whether this model shape's kernel is compiled: loaded in this process, or in numba's disk cache
    (wherever ``NUMBA_CACHE_DIR`` puts it; the index is written after the compiled code)."""
    shape = _shape(b, histories, vary, record=record)
    folder = cache_dir()
    loaded = _LOADED.get((str(folder), shape_key(shape)))
    if loaded is not None and loaded.run_blocks.signatures:
        return True
    if why_not_private(folder) is not None:
        return False
    try:
        mod = _module(shape)
        return bool(mod.run_blocks.signatures) or os.path.exists(
            mod.run_blocks._cache._cache_file._index_path
        )
    except Exception:  # numba internals moved: treat as not compiled
        return False


def run_generated(
    b: Batch,
    histories: tuple[str, ...],
    n_out: int,
    vary: frozenset[int] | None = None,
    const: list[int] | None = None,
    record: tuple[int, ...] = (),
) -> KernelOutput:
    """Integrate every variant of ``b`` with its model's generated kernel (results bitwise those of
    the reference kernel). ``b`` must be supported (:func:`unsupported` returns None). ``record``:
    nodes whose acceleration is kept at every step (``step_acceleration``)."""
    why = unsupported(b)
    if why is not None:
        raise ValueError(f"no generated kernel for this model: {why}")
    shape = _shape(b, histories, vary, const, record)
    mod = _module(shape)
    out, hist, summ = outputs(b, histories, n_out, record)
    topo, var = records(b)
    run_blocks(
        mod.run_blocks, block_starts(b.x0.shape[2], BLOCK), n_out, _constants(b, shape), topo, var, hist, summ
    )
    return finish(out, hist)
