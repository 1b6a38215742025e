"""Error types shared by every stage of the pipeline.

Invalid input is reported as :class:`InputError`, which carries *every* problem found in a file
(file, line, field path, what was expected) so that the command line can print them all at once
and exit with code 2. Nothing else in crashstudy should raise on bad user input.
"""

from __future__ import annotations

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
        where = f"{self.file}:{self.line}" if self.line is not None else f"{self.file}"
        fld = f" {self.field}:" if self.field else ""
        return f"{where}:{fld} {self.message}"


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


class VariantFailure(Exception):
    """A variant could not be run (numerical failure); recorded per variant, never fatal for a study."""
