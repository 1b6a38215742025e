"""A generated kernel's name covers the laws it calls, and a process that changes its kernel folder (``CRASHSTUDY_KERNEL_CACHE``) mid-way uses the new folder: the
kernel choice asks the new folder whether a shape is compiled, and a run writes and compiles its generated
kernel there, not in the folder it loaded the shape from first (a notebook that points the variable at
another folder between two studies)."""

from __future__ import annotations

from pathlib import Path

import pytest

from crashstudy.kernel import generated
from crashstudy.kernel.gen_shape import _shape
from helpers import _generated_parts_run, generated_parts_model, model_batch


def test_a_changed_kernel_folder_is_the_one_asked_and_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the side-by-side physics shape: compiled at start-up (tests/conftest.py), run here in this process
    _generated_parts_run(1e-4, 1e-3, 1e-3)
    model, scales = generated_parts_model(1e-4, 1e-3, 1e-3)
    batch, plan = model_batch(model, scales)
    histories = plan.topology.histories
    assert generated.is_compiled(batch, histories)
    first = Path(generated._module(_shape(batch, histories, None)).__file__).parent

    new = tmp_path / "kernels"
    new.mkdir(mode=0o700)
    with monkeypatch.context() as env:
        env.setenv("CRASHSTUDY_KERNEL_CACHE", str(new))
        assert not generated.is_compiled(batch, histories)  # nothing is compiled in the new folder
        module = generated._module(_shape(batch, histories, None))
        assert Path(module.__file__).parent == new != first
        assert not module.run_blocks.signatures  # the new folder's module, not the one compiled before
    assert generated.is_compiled(batch, histories)  # back in the first folder: its module, compiled


def test_a_kernel_name_changes_with_the_laws_it_calls(monkeypatch: pytest.MonkeyPatch) -> None:
    """numba's cache checks only the generated file's own time stamp: a crashstudy whose laws changed (a
    fixed law, a new constant) must not load a kernel compiled with the old ones, so the name (the file
    and its numba index) is a hash of the source and of every crashstudy module the source imports."""
    import hashlib
    import importlib
    import re

    model, scales = generated_parts_model(1e-4, 1e-3, 1e-3)
    batch, plan = model_batch(model, scales)
    shape = _shape(batch, plan.topology.histories, None)
    src = generated._source(shape)
    named = re.findall(r"^from (crashstudy\.\S+) import", src, flags=re.M)
    assert set(named) == {
        "crashstudy.vocabulary.codes",
        "crashstudy.kernel.laws",
        "crashstudy.kernel.step_laws",
    }
    files = b"".join(Path(str(importlib.import_module(n).__file__)).read_bytes() for n in named)
    before = hashlib.sha256(src.encode() + hashlib.sha256(files).digest()).hexdigest()[:20]
    assert generated.shape_key(shape) == before

    monkeypatch.setattr(generated, "_SOURCES", {})
    changed = hashlib.sha256(files + b"# a fixed law").digest()
    monkeypatch.setattr(generated, "laws_fingerprint", lambda modules: changed)
    assert generated._source_key(shape) == (src, hashlib.sha256(src.encode() + changed).hexdigest()[:20])
    assert generated.shape_key(shape) != before
