"""Every environment variable crashstudy reads, and the one check of each value.

:data:`VARIABLES` names each variable with the values it takes. A module that reads one calls the
parser here (the limits of the input readers have their own parsers, named in :data:`VARIABLES`), so a
wrong value is one :class:`~crashstudy.errors.InputError` naming the variable and what it allows
(exit 2), never a traceback and never silently ignored. The command line calls :func:`check` before
any command runs; ``tests/test_environment.py`` fails when a module reads a variable that is not listed.
This module imports nothing heavy: ``crashstudy --help`` does not pay for it.
"""

from __future__ import annotations

import os

from crashstudy.errors import InputError, Problem

KERNEL = "CRASHSTUDY_KERNEL"
BACKGROUND_COMPILE = "CRASHSTUDY_BACKGROUND_COMPILE"
GEN_BLOCK = "CRASHSTUDY_GEN_BLOCK"
GEN_BLOCK_DEFAULT, GEN_BLOCK_MAX = 256, 65536  # variants per block of the generated kernel
BACKGROUND = {
    "0": "never",
    "no": "never",
    "off": "never",
    "false": "never",
    "1": "auto",
    "yes": "auto",
    "on": "auto",
    "true": "auto",
    "always": "always",
}

#: every variable crashstudy reads, with the values it takes (the message of a wrong value)
VARIABLES: dict[str, str] = {
    KERNEL: "reference, generic or generated (unset: the fastest kernel that is ready)",
    BACKGROUND_COMPILE: "0 (or no, off, false: never), 1 (or yes, on, true; the default) or always",
    GEN_BLOCK: f"a whole number of variants per block of the generated kernel, 1 to {GEN_BLOCK_MAX} "
    f"(default {GEN_BLOCK_DEFAULT})",
    "CRASHSTUDY_MAX_VALUES": "a whole number of values > 0 (schema/yamlcompose.py max_values)",
    "CRASHSTUDY_MAX_WORK": "a number of element-steps > 0 (study/work.py max_work)",
    "CRASHSTUDY_KERNEL_CACHE": "a folder only you can write to (else it is skipped with a warning)",
    "NUMBA_CACHE_DIR": "a folder only you can write to (else numba's cache moves with a warning)",
}


def raw(name: str) -> str:
    """The variable's value without surrounding blanks ("" when unset)."""
    return os.environ.get(name, "").strip()


def invalid(name: str, value: str) -> InputError:
    """The input error of a wrong value: the variable, what it allows, what it holds."""
    return InputError([Problem("environment", None, name, f"expected {VARIABLES[name]}, got {value[:40]!r}")])


def kernel() -> str:
    """``CRASHSTUDY_KERNEL``: "compiled" (unset: choose) or a kernel's name."""
    value = raw(KERNEL) or "compiled"
    if value not in ("compiled", "reference", "generic", "generated"):
        raise invalid(KERNEL, value)
    return value


def background_compile() -> str:
    """``CRASHSTUDY_BACKGROUND_COMPILE``: "never", "auto" (unset) or "always"."""
    value = raw(BACKGROUND_COMPILE).lower() or "1"
    if value not in BACKGROUND:
        raise invalid(BACKGROUND_COMPILE, value)
    return BACKGROUND[value]


def gen_block() -> int:
    """``CRASHSTUDY_GEN_BLOCK``: variants per block of the generated kernel."""
    value = raw(GEN_BLOCK)
    if not value:
        return GEN_BLOCK_DEFAULT
    try:
        block = int(value.replace("_", ""))
    except ValueError:
        raise invalid(GEN_BLOCK, value) from None
    if not 1 <= block <= GEN_BLOCK_MAX:
        raise invalid(GEN_BLOCK, value)
    return block


def check() -> None:
    """Check the variables of the kernels (one InputError listing each wrong one). The readers' limits
    (``CRASHSTUDY_MAX_VALUES``, ``CRASHSTUDY_MAX_WORK``) are checked by their parsers when a file is read,
    and the cache folders by :mod:`crashstudy.kernel.cache` (a folder that is not private is skipped)."""
    problems: list[Problem] = []
    for parse in (kernel, background_compile, gen_block):
        try:
            parse()
        except InputError as exc:
            problems.extend(exc.problems)
    if problems:
        raise InputError(problems)
