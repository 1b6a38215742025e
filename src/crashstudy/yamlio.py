"""Safe YAML loading for crashstudy's model and study files.

:func:`load_yaml` reads a file into plain Python data (dict, list, str, int, float, bool, None) and
records the 1-based line of every mapping key and sequence item, for ``file:line: field: message``.
Scalars follow the YAML 1.2 core schema (``1e-3`` is a float; ``yes``/``no``/``on``/``off`` and dates
stay strings); mapping keys are always strings (their source text). Refused with an
:class:`InputError`: duplicate keys, tags beyond plain data, ``<<`` merge keys, alias bombs, nesting
deeper than :data:`MAX_DEPTH`, documents over :data:`MAX_BYTES`, integers over :data:`MAX_INT_DIGITS`
digits, several documents, a top level that is not a mapping. No other exception escapes.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from typing import Any

import yaml
from yaml.events import AliasEvent, MappingStartEvent, SequenceStartEvent, StreamEndEvent
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode

from crashstudy.errors import InputError, Problem

__all__ = ["LoadedYaml", "format_path", "load_yaml", "loads_yaml"]

MAX_BYTES = 20 * 1024 * 1024  #: largest document accepted (UTF-8 bytes)
MAX_DEPTH = 64  #: deepest nesting of mappings and lists (the top-level mapping is level 1)
MAX_ALIASES = 1000  #: most ``*alias`` references in one document
MAX_NODES = 1_000_000  #: most values in one document, each alias counted at its expanded size
MAX_INT_DIGITS = 30  #: longest integer literal (digits)

YamlPath = tuple[str | int, ...]

_T = "tag:yaml.org,2002:"
STR, INT, FLOAT, BOOL, NULL, SEQ, MAP = (_T + n for n in ("str", "int", "float", "bool", "null", "seq", "map"))
_SCALAR_TAGS = {STR: "text", INT: "an integer", FLOAT: "a number", BOOL: "true or false", NULL: "null"}

# YAML 1.2 core schema (https://yaml.org/spec/1.2.2/#1032-tag-resolution); `\Z` makes `match` whole.
_INT_RE = re.compile(r"(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)\Z")
_FLOAT_RE = re.compile(
    r"(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))\Z"
)
_BOOL_RE = re.compile(r"(?:true|True|TRUE|false|False|FALSE)\Z")
_NULL_RE = re.compile(r"(?:~|null|Null|NULL|)\Z")


def format_path(path: YamlPath) -> str:
    """Dotted field path for messages, e.g. ``springs.cabin.material`` or ``loads.0.node``."""
    return ".".join(str(part) for part in path)


@dataclass
class LoadedYaml:
    """A parsed YAML file with the line of every key and item.

    Attributes
    ----------
    data : Any
        Plain Python data; the top level is always a ``dict`` with ``str`` keys.
    text : str
        The file's text, verbatim.
    file : str
        The path as the caller gave it.
    lines : dict[tuple[str | int, ...], int]
        1-based line of every mapping key (by key path) and sequence item (by int index); ``()`` is 1.
    """

    data: Any
    text: str
    file: str
    lines: dict[YamlPath, int] = field(default_factory=dict)

    def line_of(self, path: YamlPath) -> int | None:
        """Line of `path`; if absent, of its nearest ancestor present; ``None`` if nothing known."""
        for end in range(len(path), -1, -1):
            if path[:end] in self.lines:
                return self.lines[path[:end]]
        return None

    def problem(self, path: YamlPath, message: str) -> Problem:
        """A :class:`Problem` at `path` (its line as :meth:`line_of` finds it, its dotted field)."""
        return Problem(self.file, self.line_of(path), format_path(path), message)


class _Refused(Exception):
    """A limit or rule broken while composing; `mark` is the YAML position."""

    def __init__(self, message: str, mark: Any) -> None:
        super().__init__(message)
        self.message, self.mark = message, mark


class _Loader(yaml.SafeLoader):
    """SafeLoader with core-schema resolution that counts nesting, aliases and expanded size."""

    yaml_implicit_resolvers: dict[str, list[tuple[str, re.Pattern[str]]]] = {}

    def __init__(self, stream: str) -> None:
        super().__init__(stream)
        self.depth = self.aliases = self.count = 0
        self.sizes: dict[int, int] = {}  # id(node) -> values it stands for, aliases expanded

    def _add(self, size: int, mark: Any) -> None:
        self.count += size
        if self.count > MAX_NODES:
            raise _Refused(f"document too large: more than {MAX_NODES:,} values once aliases are "
                           "expanded (refusing a possible alias bomb)", mark)

    def get_single_node(self) -> Node | None:
        self.get_event()  # stream start
        node = None if self.check_event(StreamEndEvent) else self.compose_document()
        if not self.check_event(StreamEndEvent):
            raise _Refused("expected a single YAML document, found a second one (after '---' or '...')",
                           self.peek_event().start_mark)
        return node

    def compose_node(self, parent: Node | None, index: Any) -> Node:
        event, before = self.peek_event(), self.count
        mark, anchor = event.start_mark, getattr(event, "anchor", None)
        if isinstance(event, AliasEvent):
            self.get_event()
            self.aliases += 1
            if self.aliases > MAX_ALIASES:
                raise _Refused(f"more than {MAX_ALIASES} aliases (*name); refusing a possible alias bomb", mark)
            target = self.anchors.get(anchor)
            if target is None:
                raise _Refused(f"alias *{anchor} names no anchor &{anchor} defined before it", mark)
            if id(target) not in self.sizes:
                raise _Refused(f"alias *{anchor} is inside its own anchor (recursive data is not allowed)", mark)
            self._add(self.sizes[id(target)], mark)
            # A new node (for the alias's own line) sharing the target's children: nothing is expanded.
            node = type(target)(target.tag, target.value, mark, event.end_mark)
            self.sizes[id(node)] = self.sizes[id(target)]
            return node
        if anchor is not None and anchor in self.anchors:
            raise _Refused(f"anchor &{anchor} defined twice (first at line {_line(self.anchors[anchor])})", mark)
        nested = int(self.check_event(SequenceStartEvent, MappingStartEvent))
        self.depth += nested
        if self.depth > MAX_DEPTH:
            raise _Refused(f"nesting deeper than {MAX_DEPTH} levels", mark)
        self._add(1, mark)
        node = super().compose_node(parent, index)
        self.depth -= nested
        self.sizes[id(node)] = self.count - before
        return node


for _tag, _regex, _first in (
    (BOOL, _BOOL_RE, list("tTfF")),
    (INT, _INT_RE, list("-+0123456789")),
    (FLOAT, _FLOAT_RE, list("-+0123456789.")),
    (NULL, _NULL_RE, ["~", "n", "N", ""]),
):
    _Loader.add_implicit_resolver(_tag, _regex, _first)


def _line(node: Node) -> int:
    return node.start_mark.line + 1


def _show_tag(tag: str) -> str:
    return "!!" + tag[len(_T):] if tag.startswith(_T) else tag


def _kind(node: Node) -> str:
    if isinstance(node, MappingNode):
        return "a mapping"
    return "a list" if isinstance(node, SequenceNode) else f"the value {node.value[:40]!r}"


class _Builder:
    """Turns composed nodes into plain data, recording lines and collecting problems."""

    def __init__(self, file: str) -> None:
        self.file = file
        self.lines: dict[YamlPath, int] = {(): 1}
        self.problems: list[Problem] = []

    def add(self, line: int, path: YamlPath, message: str) -> None:
        problem = Problem(self.file, line, format_path(path), message)
        if problem not in self.problems:
            self.problems.append(problem)

    def build(self, node: Node, path: YamlPath) -> Any:
        if isinstance(node, ScalarNode):
            return self.scalar(node, path)
        if len(path) >= MAX_DEPTH:  # reachable through aliases only: the composer checks the rest
            raise _Refused(f"nesting deeper than {MAX_DEPTH} levels", node.start_mark)
        is_seq = isinstance(node, SequenceNode)
        if node.tag != (SEQ if is_seq else MAP):
            self.add(_line(node), path, f"unsupported tag {_show_tag(node.tag)} on {_kind(node)}; "
                     "expected plain data without tags")
        if not is_seq:
            return self.mapping(node, path)
        items = []
        for index, item in enumerate(node.value):
            self.lines[path + (index,)] = _line(item)
            items.append(self.build(item, path + (index,)))
        return items

    def mapping(self, node: Node, path: YamlPath) -> dict[str, Any]:
        out: dict[str, Any] = {}
        first: dict[str, int] = {}
        for key_node, value_node in node.value:
            key = self.key(key_node, path)
            if key is None:
                continue
            if key in first:
                self.add(_line(key_node), path + (key,), f"duplicate key {key!r} (first at line {first[key]})")
                continue
            first[key] = self.lines[path + (key,)] = _line(key_node)
            out[key] = self.build(value_node, path + (key,))
        return out

    def key(self, node: Node, path: YamlPath) -> str | None:
        if not isinstance(node, ScalarNode):
            self.add(_line(node), path, f"expected a plain key (a name or number), found {_kind(node)}")
            return None
        if node.tag not in _SCALAR_TAGS:
            self.add(_line(node), path + (node.value,), f"unsupported tag {_show_tag(node.tag)} on a key; "
                     "expected plain data without tags")
            return None
        if node.value == "<<" and node.style is None:
            self.add(_line(node), path + ("<<",), "merge keys ('<<') are not supported (YAML 1.2 has none); "
                     "write the keys out or use a plain alias (*name)")
            return None
        return str(node.value)

    def scalar(self, node: ScalarNode, path: YamlPath) -> Any:
        tag, text = node.tag, node.value
        if tag == STR:
            return text
        if tag == NULL and _NULL_RE.match(text):
            return None
        if tag == BOOL and _BOOL_RE.match(text):
            return text.lower() == "true"
        if tag == INT and _INT_RE.match(text):
            body = text.lstrip("+-")
            base = {"0x": 16, "0o": 8}.get(body[:2], 10)
            digits = (body[2:] if base != 10 else body).lstrip("0") or "0"
            if len(digits) > MAX_INT_DIGITS:
                self.add(_line(node), path, f"number too large: an integer of {len(digits)} digits (at "
                         f"most {MAX_INT_DIGITS}); write it as a float with an exponent")
                return None
            return (-1 if text.startswith("-") else 1) * int(digits, base)
        if tag == FLOAT and _FLOAT_RE.match(text):
            lower = text.lower()
            if lower.endswith(".inf"):
                return -math.inf if lower.startswith("-") else math.inf
            return math.nan if lower == ".nan" else float(text)
        if tag in _SCALAR_TAGS:
            self.add(_line(node), path, f"expected {_SCALAR_TAGS[tag]} after {_show_tag(tag)}, found {text[:40]!r}")
        else:
            self.add(_line(node), path, f"unsupported tag {_show_tag(tag)}; expected plain data without tags")
        return None


def _syntax_message(exc: yaml.MarkedYAMLError) -> str:
    problem = " ".join(str(exc.problem or "invalid YAML").split())
    message = f"invalid YAML: {problem}"
    if exc.problem_mark is not None:
        message += f" (column {exc.problem_mark.column + 1})"
    if exc.context:
        where = f" at line {exc.context_mark.line + 1}" if exc.context_mark is not None else ""
        message += f", {' '.join(str(exc.context).split())}{where}"
    return message


def _parse(text: str, file: str) -> LoadedYaml:
    def fail(line: int | None, message: str) -> InputError:
        return InputError([Problem(file, line, "", message)])

    size = len(text) if len(text) > MAX_BYTES else len(text.encode("utf-8", "surrogatepass"))
    if size > MAX_BYTES:
        raise fail(None, f"document too large: {size:,} bytes (at most {MAX_BYTES:,}, 20 MB)")
    builder = _Builder(file)
    try:
        loader = _Loader(text)
        try:
            node = loader.get_single_node()
        finally:
            loader.dispose()
        if not isinstance(node, MappingNode):
            empty = node is None or (isinstance(node, ScalarNode) and node.tag == NULL and not node.value)
            found = "an empty document" if empty else "a list" if isinstance(node, SequenceNode) else "plain text"
            raise fail(1 if empty else _line(node), f"expected a mapping at top level (key: value lines), found {found}"
                       " (is this a crashstudy model or study file?)")  # nothing of a foreign file is quoted
        data = builder.build(node, ())
    except _Refused as exc:
        raise fail(exc.mark.line + 1, exc.message) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        raise fail(None if mark is None else mark.line + 1, _syntax_message(exc)) from None
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        raise fail(line, f"unacceptable character #x{exc.character:04x} ({exc.reason})") from None
    if builder.problems:
        raise InputError(builder.problems)
    return LoadedYaml(data=data, text=text, file=file, lines=builder.lines)


def loads_yaml(text: str, file: str = "<string>") -> LoadedYaml:
    """Parse YAML `text` as if read from `file` (see :func:`load_yaml`).

    Raises
    ------
    InputError
        For any problem with the text; no other exception escapes.
    """
    try:
        return _parse(text, file)
    except InputError:
        raise
    except Exception as exc:  # last line of defence: bad input must never produce a traceback
        detail = " ".join(f"{type(exc).__name__}: {exc}".split())[:200]
        raise InputError([Problem(file, None, "", f"could not read the YAML ({detail})")]) from exc


def load_yaml(path: str | os.PathLike[str], text: str | None = None) -> LoadedYaml:
    """Read and parse the YAML file at `path`.

    Parameters
    ----------
    path : str or os.PathLike
        The file; it is reported in messages as given.
    text : str, optional
        The file's text when the caller has already read it; the file is then not opened.

    Returns
    -------
    LoadedYaml
        The data, the verbatim text and the line of every key and item.

    Raises
    ------
    InputError
        With one :class:`Problem` (file, line, dotted field, message) per problem found.
    """
    file = os.fsdecode(path)
    if text is None:
        text = _read(file)
    return loads_yaml(text, file)


def _read(file: str) -> str:
    try:
        with open(file, "rb") as handle:
            raw = handle.read(MAX_BYTES + 1)
    except FileNotFoundError:
        reason = "file not found"
    except IsADirectoryError:
        reason = "is a directory, expected a YAML file"
    except PermissionError:
        reason = "permission denied"
    except (OSError, ValueError) as exc:
        reason = f"cannot read the file ({getattr(exc, 'strerror', None) or exc})"
    else:
        if len(raw) > MAX_BYTES:
            reason = f"document too large: more than {MAX_BYTES:,} bytes (20 MB)"
        else:
            try:
                return raw.decode("utf-8")
            except UnicodeDecodeError as exc:
                line = raw.count(b"\n", 0, exc.start) + 1
                reason = (f"not UTF-8 text: byte 0x{raw[exc.start]:02x} on line {line} cannot be decoded; "
                          "save the file as UTF-8")
    raise InputError([Problem(file, None, "", reason)])
