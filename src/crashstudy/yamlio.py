"""Safe YAML loading for crashstudy's model and study files.

:func:`load_yaml` reads a file into plain Python data (dict, list, str, int, float, bool, None) and
records the 1-based line of every mapping key and sequence item, for ``file:line: field: message``.
Scalars follow the YAML 1.2 core schema (``1e-3`` is a float; ``yes``/``no``/``on``/``off`` and dates
stay strings); mapping keys are always strings (their source text). Refused with an
:class:`InputError`: duplicate keys, tags beyond plain data, ``<<`` merge keys, alias bombs, nesting
deeper than :data:`MAX_DEPTH`, documents over :data:`MAX_BYTES` or of more than :data:`MAX_NODES` values
(the environment variable ``CRASHSTUDY_MAX_VALUES`` replaces it), integers over :data:`MAX_INT_DIGITS`
digits, several documents, a top level that is not a mapping, and anything but a regular file (a FIFO,
a device: refused before it is opened). No other exception escapes.

Parsing uses libyaml's parser when PyYAML has it (5x faster), under the same composer; syntax errors
keep the Python parser's messages. A large document is parsed once per process (:data:`CACHE_DOCUMENTS`);
each caller gets its own copy of the data.
"""

from __future__ import annotations

import gc
import math
import os
import re
import stat
from dataclasses import dataclass, field
from typing import Any

import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.events import AliasEvent, MappingStartEvent, SequenceStartEvent, StreamEndEvent
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode
from yaml.parser import Parser
from yaml.reader import Reader
from yaml.resolver import Resolver
from yaml.scanner import Scanner

try:  # libyaml, bundled with PyYAML's wheels
    from yaml._yaml import CParser
except ImportError:  # pragma: no cover - a PyYAML built without libyaml
    CParser = None

from crashstudy.errors import InputError, Problem

__all__ = ["LoadedYaml", "format_path", "load_yaml", "loads_yaml", "max_values", "not_regular"]

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
STR, INT, FLOAT, BOOL, NULL, SEQ, MAP = (_T + n for n in ("str", "int", "float", "bool", "null", "seq", "map"))
_SCALAR_TAGS = {STR: "text", INT: "an integer", FLOAT: "a number", BOOL: "true or false", NULL: "null"}

# YAML 1.2 core schema (https://yaml.org/spec/1.2.2/#1032-tag-resolution); `\Z` makes `match` whole.
_INT_RE = re.compile(r"(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)\Z")
_FLOAT_RE = re.compile(
    r"(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))\Z"
)
_BOOL_RE = re.compile(r"(?:true|True|TRUE|false|False|FALSE)\Z")
_NULL_RE = re.compile(r"(?:~|null|Null|NULL|)\Z")
_PARSED: dict[tuple[str, str, int], LoadedYaml] = {}  # (file, text, value limit) -> parsed, see loads_yaml
_IMPLICIT = ((BOOL, _BOOL_RE), (INT, _INT_RE), (FLOAT, _FLOAT_RE), (NULL, _NULL_RE))  # in Resolver's order


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
        raise InputError([Problem(MAX_VALUES_ENV, None, "", f"expected a whole number of values > 0 (the default "
                                  f"is {MAX_NODES}), got {raw[:40]!r}")])  # fmt: skip
    return value


def _too_many_values(limit: int, aliases: int, at_least: int = 0) -> str:
    if aliases:
        return (f"document too large: more than {limit:,} values once aliases are expanded (refusing a "
                "possible alias bomb)")
    count = f"at least {at_least:,} values" if at_least else f"more than {limit:,} values"
    return (f"document too large: {count} (keys, numbers, texts, lists and mappings; a chain model takes about "
            f"19 per node), at most {limit:,}: set the environment variable {MAX_VALUES_ENV} to read more")


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
        if node.value == "<<" and not node.style:  # plain: None (Python parser) or "" (libyaml)
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


def _compose(text: str, loader: type[_Counting]) -> Node | None:
    instance = loader(text)  # type: ignore[call-arg]
    try:
        return instance.get_single_node()
    finally:
        instance.dispose()  # type: ignore[attr-defined]


def _line_end(text: str, lines: int) -> int:
    """Offset just past the first ``lines`` lines of ``text``."""
    pos = -1
    for _ in range(lines):
        pos = text.find("\n", pos + 1)
        if pos < 0:
            return len(text)
    return pos + 1


def _count_events(text: str) -> None:
    """Refuse at once a document whose libyaml events (counted in C, 10^7 a second) already show more
    values than the limit: a scalar or an alias is one event and at least one value, a list or a
    mapping two events (start, end) and one value."""
    try:
        events = CParser(text).raw_parse()
    except Exception:  # a syntax error: composing reports it
        return
    limit = max_values()
    if (events - 4) // 2 > limit:  # less the stream and document start and end
        raise _Refused(_too_many_values(limit, 0, (events - 4) // 2), None)


def _compose_fast(text: str) -> Node | None:
    """Compose with libyaml when PyYAML has it, with the Python parser's messages for syntax errors.

    libyaml says less than the Python parser ("found character that cannot start any token" for a
    tab): on a syntax error within the first :data:`REPARSE_CHARS` characters, the Python parser is run
    on the text up to the line after the error and its message is used if it finds an error there too.
    """
    if _LOADER is _Loader:
        return _compose(text, _Loader)
    Reader(text)  # the Python reader's check for unacceptable characters (one regex; its messages)
    _count_events(text)
    try:
        return _compose(text, _LOADER)
    except yaml.MarkedYAMLError as fast:
        mark = fast.problem_mark or fast.context_mark
        end = len(text) if mark is None else _line_end(text, mark.line + 2)
        if end > REPARSE_CHARS:
            raise
        try:
            _compose(text[:end], _Loader)
        except yaml.MarkedYAMLError as slow:
            at = slow.problem_mark or slow.context_mark
            if mark is None or (at is not None and at.line <= mark.line):
                raise slow from None
        raise


def _parse(text: str, file: str) -> LoadedYaml:
    def fail(line: int | None, message: str) -> InputError:
        return InputError([Problem(file, line, "", message)])

    size = len(text) if len(text) > MAX_BYTES else len(text.encode("utf-8", "surrogatepass"))
    if size > MAX_BYTES:
        raise fail(None, f"document too large: {size:,} bytes (at most {MAX_BYTES:,}, 20 MB)")
    builder = _Builder(file)
    collecting = gc.isenabled()
    gc.disable()  # no cycles are made here; collecting while 10^6 nodes are alive made parsing 4x slower
    try:
        node = _compose_fast(text)
        if not isinstance(node, MappingNode):
            empty = node is None or (isinstance(node, ScalarNode) and node.tag == NULL and not node.value)
            found = "an empty document" if empty else "a list" if isinstance(node, SequenceNode) else "plain text"
            raise fail(1 if empty else _line(node), f"expected a mapping at top level (key: value lines), found {found}"
                       " (is this a crashstudy model or study file?)")  # nothing of a foreign file is quoted
        data = builder.build(node, ())
    except _Refused as exc:
        raise fail(None if exc.mark is None else exc.mark.line + 1, exc.message) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        raise fail(None if mark is None else mark.line + 1, _syntax_message(exc)) from None
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        raise fail(line, f"unacceptable character #x{exc.character:04x} ({exc.reason})") from None
    finally:
        if collecting:
            gc.enable()
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
    key = (file, text, max_values())
    cached = _PARSED.get(key)
    if cached is None:
        try:
            cached = _parse(text, file)
        except InputError:
            raise
        except Exception as exc:  # last line of defence: bad input must never produce a traceback
            detail = " ".join(f"{type(exc).__name__}: {exc}".split())[:200]
            raise InputError([Problem(file, None, "", f"could not read the YAML ({detail})")]) from exc
        if len(text) < CACHE_MIN_CHARS:
            return cached
        while len(_PARSED) >= CACHE_DOCUMENTS:
            del _PARSED[next(iter(_PARSED))]
        _PARSED[key] = cached
    # a copy: the caller may change its data (the cached one stays as parsed)
    return LoadedYaml(data=_copy(cached.data), text=text, file=file, lines=dict(cached.lines))


def _copy(data: Any) -> Any:
    """A copy of plain data (dicts and lists copied, scalars shared: they are immutable)."""
    if isinstance(data, dict):
        return {k: v if not isinstance(v, (dict, list)) else _copy(v) for k, v in data.items()}
    if isinstance(data, list):
        return [v if not isinstance(v, (dict, list)) else _copy(v) for v in data]
    return data


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


def not_regular(mode: int) -> str:
    """What a file of ``mode`` (``os.stat``) is, if it is not a regular file ("" if it is one)."""
    if stat.S_ISREG(mode):
        return ""
    if stat.S_ISDIR(mode):
        return "is a directory, expected a YAML file"
    kinds = ((stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISCHR, "a character device"),
             (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))  # fmt: skip
    kind = next((name for test, name in kinds if test(mode)), "a special file")
    return f"not a regular file: it is {kind}; expected a YAML file"


def _read(file: str) -> str:
    try:
        # refused before it is opened: opening a FIFO waits for a writer, a device may never end
        reason = not_regular(os.stat(file).st_mode)
        if not reason:
            fd = os.open(file, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))  # a FIFO swapped in: no wait
            with open(fd, "rb") as handle:
                reason = not_regular(os.fstat(fd).st_mode)
                raw = b"" if reason else handle.read(MAX_BYTES + 1)
    except FileNotFoundError:
        reason = "file not found"
    except IsADirectoryError:
        reason = "is a directory, expected a YAML file"
    except PermissionError:
        reason = "permission denied"
    except (OSError, ValueError) as exc:
        reason = f"cannot read the file ({getattr(exc, 'strerror', None) or exc})"
    if reason:
        raise InputError([Problem(file, None, "", reason)])
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
