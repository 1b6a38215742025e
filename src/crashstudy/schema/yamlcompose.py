"""The YAML composer with crashstudy's limits (used by :mod:`crashstudy.schema.yamlio`): the size, depth,
alias and value-count limits, the YAML 1.2 core-schema resolution of plain scalars, and the Python
and libyaml loaders that apply them while composing."""

from __future__ import annotations

import os
import re
from typing import Any

from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.events import AliasEvent, MappingStartEvent, SequenceStartEvent, StreamEndEvent
from yaml.nodes import Node, ScalarNode, SequenceNode
from yaml.parser import Parser
from yaml.reader import Reader
from yaml.resolver import Resolver
from yaml.scanner import Scanner

try:  # libyaml, bundled with PyYAML's wheels
    from yaml._yaml import CParser
except ImportError:  # pragma: no cover - a PyYAML built without libyaml
    CParser = None

from crashstudy.errors import InputError, Problem

MAX_BYTES = 20 * 1024 * 1024  #: largest document accepted (UTF-8 bytes)
MAX_DEPTH = 64  #: deepest nesting of mappings and lists (the top-level mapping is level 1)
MAX_ALIASES = 1000  #: most ``*alias`` references in one document
MAX_NODES = 1_000_000  #: most values in one document, each alias counted at its expanded size (default)
MAX_VALUES_ENV = "CRASHSTUDY_MAX_VALUES"  #: environment variable that replaces MAX_NODES
MAX_INT_DIGITS = 30  #: longest integer literal (digits)
CACHE_MIN_CHARS = 10_000  #: documents this long are kept parsed (validate reads a study three times)
CACHE_DOCUMENTS = 2  #: parsed documents kept (a study and its model)
REPARSE_CHARS = 200_000  #: syntax errors within this many characters get the Python parser's message

YamlPath = tuple[str | int, ...]

_T = "tag:yaml.org,2002:"
STR, INT, FLOAT, BOOL, NULL, SEQ, MAP = (
    _T + n for n in ("str", "int", "float", "bool", "null", "seq", "map")
)
_SCALAR_TAGS = {STR: "text", INT: "an integer", FLOAT: "a number", BOOL: "true or false", NULL: "null"}

# YAML 1.2 core schema (https://yaml.org/spec/1.2.2/#1032-tag-resolution); `\Z` makes `match` whole.
_INT_RE = re.compile(r"(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)\Z")
_FLOAT_RE = re.compile(
    r"(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))\Z"
)
_BOOL_RE = re.compile(r"(?:true|True|TRUE|false|False|FALSE)\Z")
_NULL_RE = re.compile(r"(?:~|null|Null|NULL|)\Z")
_IMPLICIT = ((BOOL, _BOOL_RE), (INT, _INT_RE), (FLOAT, _FLOAT_RE), (NULL, _NULL_RE))  # in Resolver's order


def _line(node: Node) -> int:
    return node.start_mark.line + 1


class _Refused(Exception):
    """A limit or rule broken while composing; `mark` is the YAML position."""

    def __init__(self, message: str, mark: Any) -> None:
        super().__init__(message)
        self.message, self.mark = message, mark


def max_values() -> int:
    """The most values a document may hold: :data:`MAX_NODES`, or the environment's :data:`MAX_VALUES_ENV`."""
    raw = os.environ.get(MAX_VALUES_ENV, "").strip()
    if not raw:
        return MAX_NODES
    try:
        value = int(raw.replace("_", ""))
    except ValueError:
        value = 0
    if value <= 0:
        raise InputError(
            [
                Problem(
                    MAX_VALUES_ENV,
                    None,
                    "",
                    f"expected a whole number of values > 0 (the default is {MAX_NODES}), got {raw[:40]!r}",
                )
            ]
        )
    return value


def _too_many_values(limit: int, aliases: int, at_least: int = 0) -> str:
    if aliases:
        return (
            f"document too large: more than {limit:,} values once aliases are expanded (refusing a "
            "possible alias bomb)"
        )
    count = f"at least {at_least:,} values" if at_least else f"more than {limit:,} values"
    return (
        f"document too large: {count} (keys, numbers, texts, lists and mappings; a chain model takes about "
        f"19 per node), at most {limit:,}: set the environment variable {MAX_VALUES_ENV} to read more"
    )


class _Counting(Composer):
    """A composer that counts nesting, aliases and expanded size (shared by the C and the Python parser)."""

    depth: int
    aliases: int
    count: int
    limit: int
    sizes: dict[int, int]

    def _start_counting(self) -> None:
        self.depth = self.aliases = self.count = 0
        self.limit = max_values()
        self.sizes = {}  # id(node) -> values it stands for, aliases expanded

    def _add(self, size: int, mark: Any) -> None:
        self.count += size
        if self.count > self.limit:
            raise _Refused(_too_many_values(self.limit, self.aliases), mark)

    def get_single_node(self) -> Node | None:
        self.get_event()  # stream start
        node = None if self.check_event(StreamEndEvent) else self.compose_document()
        if not self.check_event(StreamEndEvent):
            raise _Refused(
                "expected a single YAML document, found a second one (after '---' or '...')",
                self.peek_event().start_mark,
            )
        return node

    def compose_node(self, parent: Node | None, index: Any) -> Node:
        event, before = self.peek_event(), self.count
        mark, anchor = event.start_mark, getattr(event, "anchor", None)
        if isinstance(event, AliasEvent):
            self.get_event()
            self.aliases += 1
            if self.aliases > MAX_ALIASES:
                raise _Refused(
                    f"more than {MAX_ALIASES} aliases (*name); refusing a possible alias bomb", mark
                )
            target = self.anchors.get(anchor)
            if target is None:
                raise _Refused(f"alias *{anchor} names no anchor &{anchor} defined before it", mark)
            if id(target) not in self.sizes:
                raise _Refused(
                    f"alias *{anchor} is inside its own anchor (recursive data is not allowed)", mark
                )
            self._add(self.sizes[id(target)], mark)
            # A new node (for the alias's own line) sharing the target's children: nothing is expanded.
            node = type(target)(target.tag, target.value, mark, event.end_mark)
            return node
        if anchor is not None and anchor in self.anchors:
            raise _Refused(
                f"anchor &{anchor} defined twice (first at line {_line(self.anchors[anchor])})", mark
            )
        nested = int(self.check_event(SequenceStartEvent, MappingStartEvent))
        self.depth += nested
        if self.depth > MAX_DEPTH:
            raise _Refused(f"nesting deeper than {MAX_DEPTH} levels", mark)
        self._add(1, mark)
        node = super().compose_node(parent, index)
        self.depth -= nested
        if anchor is not None:  # a possible alias target: what it stands for (absent while it is composed)
            self.sizes[id(node)] = self.count - before
        return node

    def resolve(self, kind: type[Node], value: str | None, implicit: tuple[bool, bool]) -> str:
        """The core-schema tag of an untagged node (what Resolver finds with the resolvers below, faster)."""
        if kind is ScalarNode:
            if implicit[0]:
                for tag, regex in _IMPLICIT:
                    if regex.match(value):  # type: ignore[arg-type]
                        return tag
            return STR
        return SEQ if kind is SequenceNode else MAP

    def descend_resolver(self, current_node: Any, current_index: Any) -> None:
        pass  # no path resolvers

    def ascend_resolver(self) -> None:
        pass


class _Loader(_Counting, Reader, Scanner, Parser, SafeConstructor, Resolver):
    """The pure-Python parser with core-schema resolution (used when PyYAML has no libyaml)."""

    yaml_implicit_resolvers: dict[str, list[tuple[str, re.Pattern[str]]]] = {}

    def __init__(self, stream: str) -> None:
        Reader.__init__(self, stream)
        Scanner.__init__(self)
        Parser.__init__(self)
        Composer.__init__(self)
        SafeConstructor.__init__(self)
        Resolver.__init__(self)
        self._start_counting()


if CParser is not None:

    class _CLoader(_Counting, CParser, SafeConstructor, Resolver):  # type: ignore[misc,valid-type]
        """libyaml's parser (about 5x faster) under the same counting composer and resolution."""

        def __init__(self, stream: str) -> None:
            CParser.__init__(self, stream)
            Composer.__init__(self)
            SafeConstructor.__init__(self)
            Resolver.__init__(self)
            self._start_counting()


for _tag, _regex, _first in (
    (BOOL, _BOOL_RE, list("tTfF")),
    (INT, _INT_RE, list("-+0123456789")),
    (FLOAT, _FLOAT_RE, list("-+0123456789.")),
    (NULL, _NULL_RE, ["~", "n", "N", ""]),
):
    _Loader.add_implicit_resolver(_tag, _regex, _first)
_LOADER: type[_Counting] = _Loader
if CParser is not None:
    _CLoader.yaml_implicit_resolvers = _Loader.yaml_implicit_resolvers
    _LOADER = _CLoader
