"""``results.zarr``: the result store in Zarr v3, through the subset of the netCDF4 API that the writer
(:mod:`crashstudy.results.store`) and the checks (:mod:`crashstudy.results.integrity`) use.

:class:`ZarrFile` looks like an open ``netCDF4.Dataset`` (``createDimension``, ``createVariable``,
``variables``, ``dimensions``, ``ncattrs``/``getncattr``/``setncatts``, ``sync``, ``close``), so the very
code that writes ``results.nc`` writes ``results.zarr``: the same variables, dims, attributes, fill values,
checksums and run id. Each variable is a Zarr array (``dimension_names`` = the netCDF dims; zstd
compressed; chunked along ``variant`` by the run's chunk size, so that each chunk a run computes is
one stored object per variable), and xarray reads it as it reads the netCDF file (``_FillValue`` and
``_Encoding`` attributes as xarray writes them). Dimensions of no variable's first axis and unlimited
ones (the text tables) are kept in the group's ``crashstudy_dims`` attribute.

The store is a folder: it is built as ``results.zarr.partial`` and renamed to ``results.zarr`` when
complete, like the netCDF file. A folder cannot replace a folder by ``rename``: a finished store that
replaces an older one is swapped with it in one step (:func:`exchange`, Linux ``renameat2``), so the
folder always holds a whole ``results.zarr``. Its size for the manifest is the sum of its files' sizes (:func:`store_size`).
"""

from __future__ import annotations

import json
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

ZARR_FINAL, ZARR_PARTIAL = "results.zarr", "results.zarr.partial"
DIMS = "crashstudy_dims"  # group attribute: {dimension: length} (None while it grows)


def _zarr() -> Any:
    import zarr

    try:  # the CF character arrays ('S1') have no Zarr v3 specification yet: zarr says so on every access
        from zarr.core.dtype.common import UnstableSpecificationWarning

        warnings.filterwarnings("ignore", category=UnstableSpecificationWarning)
    except ImportError:
        pass
    return zarr


def _plain(value: Any) -> Any:
    """An attribute value as JSON: numpy scalars and arrays as Python numbers and lists."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


class _Dim:
    def __init__(self, size: int) -> None:
        self.size = size

    def __len__(self) -> int:
        return self.size


class ZarrVariable:
    """One array of the store, indexed like a netCDF4 variable (no masking: values as stored)."""

    def __init__(self, owner: ZarrFile, name: str, array: Any) -> None:
        object.__setattr__(self, "_owner", owner)
        object.__setattr__(self, "_array", array)
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "dimensions", tuple(array.metadata.dimension_names or ()))
        object.__setattr__(
            self,
            "dtype",
            np.dtype(
                array.dtype.to_native_dtype() if hasattr(array.dtype, "to_native_dtype") else array.dtype
            ),
        )

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(self._array.shape)

    @property
    def ndim(self) -> int:
        return len(self.shape)

    def __getitem__(self, key: Any) -> np.ndarray:
        return np.asarray(self._array[key])

    def __setitem__(self, key: Any, value: Any) -> None:
        if isinstance(key, slice) and key.stop is not None and key.stop > self._array.shape[0]:
            self._array.resize((key.stop, *self._array.shape[1:]))  # an unlimited dimension grows
            self._owner._grown(self.dimensions[0], key.stop)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # zarr's note that 'S1' has no v3 specification yet
            self._array[key] = np.asarray(value).astype(self.dtype, copy=False)

    def set_auto_mask(self, flag: bool) -> None:
        """Values are never masked here (netCDF4's switch, kept for the shared code)."""

    def set_auto_chartostring(self, flag: bool) -> None:
        """Character arrays are returned as such (netCDF4's switch, kept for the shared code)."""

    def ncattrs(self) -> list[str]:
        return list(self._array.attrs)

    def getncattr(self, name: str) -> Any:
        return self._array.attrs[name]

    def __getattr__(self, name: str) -> Any:
        try:
            return self._array.attrs[name]
        except KeyError:
            raise AttributeError(name) from None

    def __setattr__(self, name: str, value: Any) -> None:
        if name == "_Encoding" or not name.startswith("_"):
            self._array.attrs[name] = _plain(value)
        else:
            object.__setattr__(self, name, value)


class ZarrFile:
    """A Zarr v3 group opened like a ``netCDF4.Dataset`` (see the module docstring). ``mode``: ``"w"``
    creates the folder (it must not exist), ``"a"`` writes into it, ``"r"`` reads."""

    def __init__(self, path: str | os.PathLike[str], mode: str = "r", chunk: int = 4096) -> None:
        zarr = _zarr()
        self.path = Path(path)
        self.chunk = chunk
        self._open = True
        if mode == "w":
            self.group = zarr.open_group(str(self.path), mode="w-", zarr_format=3)
            self.group.attrs[DIMS] = {}
        else:
            if not self.path.is_dir():
                raise OSError(f"{self.path} is not a Zarr store (no such folder)")
            self.group = zarr.open_group(str(self.path), mode="r" if mode == "r" else "r+", zarr_format=3)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # zarr's note that 'S1' has no v3 specification yet
            arrays = sorted(self.group.arrays())
        self.variables: dict[str, ZarrVariable] = {name: ZarrVariable(self, name, a) for name, a in arrays}

    @property
    def dimensions(self) -> dict[str, _Dim]:
        stored = dict(self.group.attrs.get(DIMS, {}))
        return {d: _Dim(int(n)) for d, n in stored.items()}

    def _grown(self, dim: str, size: int) -> None:
        dims = dict(self.group.attrs.get(DIMS, {}))
        dims[dim] = max(int(dims.get(dim, 0)), size)
        self.group.attrs[DIMS] = dims

    def createDimension(self, name: str, size: int | None) -> None:  # noqa: N802 (netCDF4's name)
        dims = dict(self.group.attrs.get(DIMS, {}))
        dims[name] = 0 if size is None else int(size)
        self.group.attrs[DIMS] = dims

    def createVariable(
        self,
        name: str,
        dtype: str,
        dims: tuple[str, ...],
        fill_value: Any = None,  # noqa: N802
        chunksizes: list[int] | None = None,
        **_: Any,
    ) -> ZarrVariable:
        """An array of ``dims`` (netCDF4's arguments; compression is always zstd, chunks along ``variant``
        are the run's chunk size)."""
        from xarray.backends.zarr import FillValueCoder

        sizes = self.dimensions
        shape = tuple(len(sizes[d]) for d in dims)
        chunks = list(chunksizes or shape)
        if dims[:1] == ("variant",):
            chunks[0] = self.chunk
        chunks = [max(1, int(c)) for c in chunks]
        np_dtype = np.dtype(dtype)
        fill = fill_value if fill_value is not None else (np.nan if np_dtype.kind == "f" else 0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # 'S1' (CF character arrays) has no Zarr v3 specification yet
            array = self.group.create_array(
                name,
                shape=shape,
                dtype=np_dtype,
                chunks=tuple(chunks),
                fill_value=fill if np_dtype.kind != "S" else b"",
                dimension_names=list(dims),
            )
        if fill_value is not None:  # xarray masks by the _FillValue attribute (Zarr v3, as it writes it)
            array.attrs["_FillValue"] = _plain(FillValueCoder.encode(fill_value, np_dtype))
        var = ZarrVariable(self, name, array)
        self.variables[name] = var
        return var

    def ncattrs(self) -> list[str]:
        return [k for k in self.group.attrs if k != DIMS]

    def getncattr(self, name: str) -> Any:
        if name == DIMS:
            raise AttributeError(name)
        return self.group.attrs[name]

    def setncatts(self, attrs: dict[str, Any]) -> None:
        self.group.attrs.update({k: _plain(v) for k, v in attrs.items()})

    def sync(self) -> None:
        """Every write is on disk when it returns (one object per chunk)."""

    def isopen(self) -> bool:
        return self._open

    def close(self) -> None:
        self._open = False

    def __enter__(self) -> ZarrFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def store_size(path: Path) -> int:
    """Bytes of a Zarr store: the sum of the sizes of its regular files (links are not followed)."""
    total = 0
    for root, _, files in os.walk(path):
        for f in files:
            st = os.lstat(os.path.join(root, f))
            total += st.st_size
    return total


RENAME_EXCHANGE = 2  # renameat2 flag (Linux >= 3.15): swap two names in one step


def exchange(a: Path, b: Path) -> bool:
    """Swap the entries ``a`` and ``b`` (both must exist) in one atomic step; False where the system or
    file system cannot (then nothing was changed)."""
    import ctypes
    import sys

    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd = -100
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if fn(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (22, 38, 95):  # EINVAL, ENOSYS, EOPNOTSUPP: not supported here
        return False
    raise OSError(err, os.strerror(err), str(a))


def variant_chunk(path: Path) -> int | None:
    """The chunk length along ``variant`` of an existing store (None if it has none)."""
    try:
        meta = json.loads((path / "done" / "zarr.json").read_text())
        return int(meta["chunk_grid"]["configuration"]["chunk_shape"][0])
    except (OSError, ValueError, KeyError, IndexError):
        return None
