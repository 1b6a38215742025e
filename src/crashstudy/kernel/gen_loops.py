"""Loops over constant tables for the cold parts of a generated kernel (a block's set-up, the results of a
lane, the histories): one short loop per input or output array instead of one emitted line per node,
spring or curve knot. The hot step (passes A, B and K) stays unrolled; what runs once per block, per
ended lane or per sampled step reads its row numbers from a table, a module constant of the generated
source (``_T0 = np.array(...)``, numba freezes it into the machine code). Each table row is
``[row * ROW, index, ...]``: where the number goes in the work array ``Z``, and where it comes from.

A compile costs roughly 0.6-0.9 CPU s per 1000 characters of emitted code
(benchmarks/results/generated_source.md), and a user's first run of a new model shape waits for it: these
loops do the same arithmetic, in the same order where an order matters (the sums), in fewer lines.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from crashstudy.kernel.gen_rows import Key
    from crashstudy.kernel.gen_shape import Layout

# (row, array, indices before the variant's): ``Z[row] = array[indices..., q]``
Load = tuple["Key", str, tuple[int, ...]]


def loads(g: Layout, ind: str, items: list[Load]) -> None:
    """Lane ``w`` (variant ``q``) takes each ``Z[row] = array[idx..., q]`` of ``items``: one loop per
    array (in the order the arrays first appear; the stores are independent), a single store as it is."""
    groups: dict[tuple[str, int], list[list[int]]] = {}
    for key, arr, idx in items:
        groups.setdefault((arr, len(idx)), []).append([g.R.row(key) * g.R.stride, *idx])
    for (arr, rank), rows in groups.items():
        if len(rows) == 1:
            at = ", ".join([*(str(i) for i in rows[0][1:]), "q"])
            g.emit(f"{ind}Z[{rows[0][0]} + w] = {arr}[{at}]")
            continue
        t = g.table(rows)
        at = ", ".join([*(f"{t}[i, {c}]" for c in range(1, rank + 1)), "q"])
        g.emit(f"{ind}for i in range({len(rows)}):")
        g.emit(f"{ind}    Z[{t}[i, 0] + w] = {arr}[{at}]")


def stores(g: Layout, ind: str, arr: str, items: list[tuple[int, Key]], value: str = "{}") -> None:
    """``arr[i, q] = value(Z[row])`` for each (i, row) of ``items``, one loop (``value`` formats the row's
    element: ``"np.sqrt({})"``)."""
    if not items:
        return
    if len(items) == 1:
        i, key = items[0]
        g.emit(f"{ind}{arr}[{i}, q] = {value.format(g.R[key])}")
        return
    t = g.table([[i, g.R.row(key) * g.R.stride] for i, key in items])
    g.emit(f"{ind}for i in range({len(items)}):")
    g.emit(f"{ind}    {arr}[{t}[i, 0], q] = {value.format(f'Z[{t}[i, 1] + w]')}")
