"""Study factors: the axes that vary independently. The paths of a ``zip`` group advance together, so
they are one factor (no two variants differ in one of them alone); every other axis is a factor of its
own. Plots, ``compare`` and ``sensitivity`` name a zip group once, by :func:`factor_name`, and show
the values of its first path."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any


def zip_groups(attrs: dict[str, Any]) -> list[list[str]]:
    """The ``zip`` groups of the study stored with the results (its ``study_yaml``), paths in file order."""
    import yaml

    try:
        data = yaml.safe_load(str(attrs.get("study_yaml", "")) or "{}") or {}
    except yaml.YAMLError:
        return []
    groups = data.get("zip") if isinstance(data, dict) else None
    return [[str(p) for p in g] for g in groups or [] if isinstance(g, dict)]


def factors(attrs: dict[str, Any], axes: Sequence[str]) -> dict[str, list[str]]:
    """First path -> every path of its factor, for the ``axes`` given (in their order)."""
    group_of = {p: g for g in zip_groups(attrs) for p in g}
    out: dict[str, list[str]] = {}
    seen: set[str] = set()
    for a in axes:
        if a in seen:
            continue
        members = [p for p in group_of.get(a, [a]) if p in axes] or [a]
        seen.update(members)
        out[members[0]] = members
    return out


def factor_name(paths: Sequence[str]) -> str:
    """``path`` for a single axis; ``zip: a, b, ... (n paths)`` for a zip group."""
    if len(paths) == 1:
        return paths[0]
    shown = ", ".join(paths[:2]) + (", ..." if len(paths) > 2 else "")
    return f"zip: {shown} ({len(paths)} paths)"
