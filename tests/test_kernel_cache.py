"""The compiled-kernel cache is private to its user (a planted numba index must never be loaded).

numba unpickles its cache index; whoever can write into the cache folder can run code as the user
of crashstudy. These tests plant folders as another local user would (group/other-writable, another
owner, a symbolic link) and a malicious index, and check that none is used.
"""

from __future__ import annotations

import os
import pickle
import stat
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

from crashstudy.arrays.batch import build_batch
from crashstudy.kernel import cache, generated
from helpers import model_plan

MODEL = {
    "name": "cache-probe",
    "units": "SI",
    "nodes": {"a": {"position": [0.0], "fixed": True}, "b": {"position": [1.0], "mass": 1.0}},
    "springs": {"s": {"nodes": ["a", "b"], "material": {"type": "linear_elastic", "stiffness": 100.0}}},
    "initial_velocity": {"b": [1.0]},
    "end_time": 0.05,
    "output": {"histories": "none"},
}


class _Pwn:
    """Unpickling this writes a marker file: proof that a planted index was loaded."""

    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):  # type: ignore[no-untyped-def]
        return (Path.write_text, (self.marker, "code from a planted cache ran"))


def _fresh(env: str | None, home: Path) -> tuple[Path, list[str]]:
    cache._cache_dir.cache_clear()
    cache._fallback.cache_clear()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        folder = cache._cache_dir(env, str(home))
    cache._cache_dir.cache_clear()
    cache._fallback.cache_clear()
    return folder, [str(w.message) for w in caught if issubclass(w.category, cache.KernelCacheWarning)]


def test_new_cache_folder_is_created_private(tmp_path: Path) -> None:
    folder, said = _fresh(None, tmp_path)
    assert folder == tmp_path / ".cache" / "crashstudy" / "kernels"
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    assert said == []


def test_writable_by_others_cache_is_skipped_with_a_warning(tmp_path: Path) -> None:
    planted = tmp_path / "shared"
    planted.mkdir()
    os.chmod(planted, 0o777)
    folder, said = _fresh(str(planted), tmp_path / "home")
    assert folder != planted and folder == tmp_path / "home" / ".cache" / "crashstudy" / "kernels"
    assert len(said) == 1 and "group or others may write" in said[0] and "0777" in said[0]


def test_symlinked_cache_is_skipped(tmp_path: Path) -> None:
    real = tmp_path / "real"
    real.mkdir(mode=0o700)
    link = tmp_path / "link"
    link.symlink_to(real)
    folder, said = _fresh(str(link), tmp_path / "home")
    assert folder != link and len(said) == 1 and "symbolic link" in said[0]


def test_cache_of_another_user_is_skipped(tmp_path: Path) -> None:
    if os.geteuid() == 0:  # root can hand a folder to another user id
        other = tmp_path / "other"
        other.mkdir(mode=0o700)
        os.chown(other, 4242, -1)
        owner = 4242
    else:  # a folder that exists and belongs to root
        other, owner = Path("/"), 0
    folder, said = _fresh(str(other), tmp_path / "home")
    assert folder != other and len(said) == 1 and f"belongs to user id {owner}" in said[0]


def test_unusable_home_reuses_one_private_folder_per_user_in_the_temp_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Before: every run made a fresh crashstudy-kernels-XXXX folder (~400 KB each, never removed, and its
    kernels never reused); now every run of this user takes crashstudy-kernels-<uid>."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    blocker = tmp_path / "file"
    blocker.write_text("")
    folder, said = _fresh(None, blocker / "home")  # a home under a regular file cannot be created
    assert folder == tmp_path / f"crashstudy-kernels-{os.geteuid()}"
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700 and cache.why_not_private(folder) is None
    assert len(said) == 1 and "cannot create it" in said[0]
    again, _ = _fresh(None, blocker / "home")
    assert again == folder
    assert sorted(p.name for p in tmp_path.glob("crashstudy-kernels-*")) == [folder.name]


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to hand the folder to another user")
def test_a_per_user_temp_folder_made_by_another_user_is_not_used_and_the_fresh_one_is_removed(
    tmp_path: Path,
) -> None:
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    os.chmod(tmpdir, 0o1777)
    taken = tmpdir / f"crashstudy-kernels-{os.geteuid()}"
    taken.mkdir(mode=0o700)
    os.chown(taken, 65534, -1)  # made first by user nobody
    blocker = tmp_path / "blocker"
    blocker.write_text("")
    env = {k: v for k, v in os.environ.items() if k not in ("CRASHSTUDY_KERNEL_CACHE", "NUMBA_CACHE_DIR")}
    env.update(HOME=str(blocker / "home"), TMPDIR=str(tmpdir))
    code = "from crashstudy.kernel import cache; print(cache.cache_dir())"
    done = subprocess.run(
        [sys.executable, "-W", "always", "-c", code], capture_output=True, text=True, env=env, timeout=120
    )
    used = Path(done.stdout.strip())
    assert done.returncode == 0 and used.parent == tmpdir and used != taken, done.stderr
    assert "belongs to user id 65534" in done.stderr
    assert not used.exists(), "the fresh folder is removed when the process ends"
    assert sorted(p.name for p in tmpdir.iterdir()) == [taken.name]


def test_a_private_folder_inside_a_folder_others_may_write_is_not_private(tmp_path: Path) -> None:
    """Another user could rename it away and put their own folder (and pickles) in its place."""
    open_parent = tmp_path / "open"
    open_parent.mkdir()
    os.chmod(open_parent, 0o777)
    inner = open_parent / "kernels"
    inner.mkdir(mode=0o700)
    assert "may write into the folder" in (cache.why_not_private(inner) or "")
    os.chmod(open_parent, 0o1777)  # sticky, as /tmp: others cannot rename what is ours
    assert cache.why_not_private(inner) is None


@pytest.mark.parametrize("how", ["mode 0777", "owned by nobody"])
def test_planted_index_in_a_shared_numba_cache_is_never_loaded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, how: str
) -> None:
    """Before: with NUMBA_CACHE_DIR a folder another user can write, numba unpickled the index planted
    there at the first call of a compiled function (the marker was written, exit 0, no warning)."""
    from numba.core import caching, config

    from crashstudy.kernel import laws

    if how == "owned by nobody" and os.geteuid() != 0:
        pytest.skip("needs root to hand the folder to another user")
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o700)
    monkeypatch.setattr(config, "CACHE_DIR", str(shared))
    index = Path(caching.FunctionCache(laws.linear_force.py_func)._cache_file._index_path)
    assert index.is_relative_to(shared)
    marker = tmp_path / "pwned"
    index.write_bytes(pickle.dumps(_Pwn(marker)))
    for path in (shared, *index.relative_to(shared).parents, index.relative_to(shared)):
        where = shared / path
        if how == "mode 0777":
            os.chmod(where, 0o777)
        else:
            os.chown(where, 65534, -1)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(shared), CRASHSTUDY_KERNEL_CACHE=str(tmp_path / "kernels"))
    code = (
        "import crashstudy\nfrom crashstudy.kernel import cache, laws\ncache.cache_dir()\n"
        "print(laws.linear_force(2.0, 3.0))"
    )
    done = subprocess.run(
        [sys.executable, "-W", "always", "-c", code], capture_output=True, text=True, env=env, timeout=300
    )
    assert not marker.exists(), "a planted numba index was unpickled"
    assert done.returncode == 0 and done.stdout.strip() == "6.0", done.stderr
    assert f"numba cache {shared} (NUMBA_CACHE_DIR) not used" in done.stderr
    assert list((tmp_path / "kernels" / "numba").rglob("*.nbi")), "numba's cache moved into the kernel folder"
    model = tmp_path / "model.yaml"  # the command line says it on one line
    model.write_text(yaml.safe_dump(MODEL, sort_keys=False))
    cli = subprocess.run(
        [sys.executable, "-m", "crashstudy.cli", "simulate", str(model), "-o", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        env=dict(env, CRASHSTUDY_KERNEL="reference"),
        timeout=300,
    )
    assert cli.returncode == 0 and not marker.exists(), cli.stderr
    assert [line for line in cli.stderr.splitlines() if "NUMBA_CACHE_DIR" in line] == [
        f"warning: numba cache {shared} (NUMBA_CACHE_DIR) not used: "
        + (
            "group or others may write into it (mode 0777)"
            if how == "mode 0777"
            else f"it belongs to user id 65534, not to this user ({os.geteuid()})"
        )
        + f"; numba's compiled code goes to {tmp_path / 'kernels' / 'numba'}"
    ]


def test_planted_numba_index_in_the_old_shared_temp_folder_is_never_loaded(tmp_path: Path) -> None:
    """Before the fix: with HOME unusable the cache fell back to $TMPDIR/crashstudy-kernels; a local user
    who created it first and planted a numba index there ran code as the crashstudy user (exit 0)."""
    plan = model_plan(MODEL)
    batch, _ = build_batch(plan.topology, plan.params(0, 1), plan.interval)
    shape = generated._shape(batch, plan.topology.histories, frozenset())
    src, key = generated._source(shape), generated.shape_key(shape)  # the file name the run looks for
    lines = src.splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("def run_blocks"))
    deco = first - 1 if lines[first - 1].startswith("@") else first
    tmpdir = tmp_path / "tmp"
    planted = tmpdir / "crashstudy-kernels"
    (planted / "__pycache__").mkdir(parents=True)
    for d in (planted, planted / "__pycache__"):
        os.chmod(d, 0o777)  # as another user would leave it
    (planted / f"k_{key}.py").write_text(src)
    marker = tmp_path / "pwned"
    tag = f"py{sys.version_info.major}{sys.version_info.minor}"
    for lineno in {deco + 1, first + 1}:
        (planted / "__pycache__" / f"k_{key}.run_blocks-{lineno}.{tag}.nbi").write_bytes(
            pickle.dumps(_Pwn(marker))
        )
    model = tmp_path / "model.yaml"
    model.write_text(yaml.safe_dump(MODEL, sort_keys=False))
    blocker = tmp_path / "blocker"
    blocker.write_text("")
    env = {k: v for k, v in os.environ.items() if k != "CRASHSTUDY_KERNEL_CACHE"}
    env.update(HOME=str(blocker / "home"), TMPDIR=str(tmpdir), CRASHSTUDY_KERNEL="generated")
    done = subprocess.run(
        [sys.executable, "-m", "crashstudy.cli", "simulate", str(model), "-o", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert not marker.exists(), "a planted numba index was unpickled"
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and "warning: kernel cache" in done.stderr
    # the run still computed the right answer: F(t) = v0 sqrt(k m) sin(omega t), omega = 10 rad/s, rising until 0.05 s
    import xarray as xr

    with xr.open_dataset(tmp_path / "out" / "results.nc") as ds:
        assert float(ds["peak_force"].values.ravel()[0]) == pytest.approx(10.0 * np.sin(0.5), rel=2e-3)
