"""Error types shared by every stage of the pipeline.

Invalid input is reported as :class:`InputError`, which carries *every* problem found in a file
(file, line, field path, what was expected) so that the command line can print them all at once
and exit with code 2. Nothing else in crashstudy should raise on bad user input.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field


class CrashstudyWarning(UserWarning):
    """Base class of the warnings crashstudy itself emits (the test suite turns them into errors)."""


@dataclass(frozen=True)
class Problem:
    """One thing wrong with an input file.

    Attributes
    ----------
    file : str
        Path of the file as the user named it.
    line : int | None
        1-based line number in ``file`` (``None`` when the problem has no single place, e.g. a
        missing top-level key; then the line of the enclosing mapping is used when known).
    field : str
        Dotted field path, e.g. ``springs.cabin.material.stiffness``; ``""`` for the whole file.
    message : str
        What was wrong and what was expected.
    """

    file: str
    line: int | None
    field: str
    message: str

    def format(self) -> str:
        where = f"{printable(self.file)}:{self.line}" if self.line is not None else printable(self.file)
        fld = f" {printable(self.field)}:" if self.field else ""
        return f"{where}:{fld} {printable(self.message, MAX_MESSAGE)}"


MAX_MESSAGE = 600  #: characters of one problem's message that are printed (a longer one ends in "...")
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")


def printable(text: str, limit: int | None = None) -> str:
    """``text`` safe for a terminal: control characters (ESC sequences, newlines, NUL) shown as escapes
    (``\\x1b``), so a quoted key or path can neither rewrite the screen nor split a message line."""
    out = _CONTROL.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), str(text))
    return out if limit is None or len(out) <= limit else out[: limit - 3] + "..."


@dataclass
class InputError(Exception):
    """Raised when an input file is invalid; holds every :class:`Problem` found."""

    problems: list[Problem] = field(default_factory=list)

    def __post_init__(self) -> None:
        super().__init__(self.format())

    def format(self, limit: int = 40) -> str:
        lines = [p.format() for p in self.problems[:limit]]
        if len(self.problems) > limit:
            lines.append(f"... and {len(self.problems) - limit} more problems")
        return "\n".join(lines)

    def __str__(self) -> str:  # dataclass would otherwise print the repr
        return self.format()
