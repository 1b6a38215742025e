"""A text variable of a result stored as codes into its table, decoded only where it is indexed (what
:func:`crashstudy.results.tables.decode_texts` gives a large result: decoded whole, a 10^8-variant result
would be GBs of texts). Its own module: it subclasses xarray's backend array, and xarray is imported only
where results are read."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from xarray.backends import BackendArray
from xarray.core import indexing


class _Texts(BackendArray):
    """The texts of ``codes`` (an xarray Variable) in the table ``cats``, 'nan' where no text; ``indices``
    turns stored codes into indices into ``cats`` (-1: none)."""

    def __init__(self, codes: Any, cats: list[str], indices: Callable[[np.ndarray, int], np.ndarray]) -> None:
        self.codes, self.table, self.indices = codes, np.asarray([*cats, "nan"], dtype=str), indices
        self.shape, self.dtype = codes.shape, self.table.dtype

    def __getitem__(self, key: Any) -> np.ndarray:
        return indexing.explicit_indexing_adapter(key, self.shape, indexing.IndexingSupport.BASIC, self._read)

    def _read(self, key: tuple[Any, ...]) -> np.ndarray:
        codes = self.indices(np.asarray(self.codes[key].values), len(self.table) - 1)
        return self.table[codes]  # -1: the last entry, 'nan'


def lazy_texts(codes: Any, cats: list[str], indices: Callable[[np.ndarray, int], np.ndarray]) -> Any:
    """The lazily decoded texts of the codes variable ``codes`` (an xarray Variable) in the table ``cats``."""
    return indexing.LazilyIndexedArray(_Texts(codes, cats, indices))
