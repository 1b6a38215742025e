"""Command-line arguments that name a summary column (``summary --sort``, ``--exceed``, ``sensitivity``):
one rule for matching them, and the problem a bad argument reports. Imported by ``cli/main.py`` and
``cli/explore.py`` alike, so neither imports the other for it."""

from __future__ import annotations

from crashstudy.errors import InputError, Problem


def arg_problem(where: str, msg: str) -> Problem:
    """A problem with a command-line argument (no file line, no field)."""
    return Problem(where, None, "", msg)


def match_column(where: str, wanted: str, columns: list[str]) -> str:
    """The column ``wanted`` names: itself, or the one column it is a part of."""
    if wanted in columns:
        return wanted
    hits = [c for c in columns if wanted in c]
    named = [
        c for c in hits if c.split(".", 1)[0] == wanted
    ]  # "hic15": hic15.occupant, not hic15_t1.occupant
    if len(hits) == 1 or len(named) == 1:
        return hits[0] if len(hits) == 1 else named[0]
    if hits:
        raise InputError([arg_problem(where, f"--sort {wanted!r} is ambiguous: it matches {hits}; name one")])
    import difflib

    close = difflib.get_close_matches(wanted, columns, 5)
    raise InputError([arg_problem(where, f"no column {wanted!r}; columns like it: {close or columns}")])
