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
from dataclasses import dataclass, field
from typing import Any

import yaml
from yaml.nodes import MappingNode, Node, ScalarNode, SequenceNode
from yaml.reader import Reader

from crashstudy.safefs import file_kind

try:  # libyaml, bundled with PyYAML's wheels
    from yaml._yaml import CParser
except ImportError:  # pragma: no cover - a PyYAML built without libyaml
    CParser = None

from crashstudy.errors import InputError, Problem

__all__ = ["LoadedYaml", "format_path", "load_yaml", "loads_yaml", "max_values", "not_regular"]

from crashstudy.schema.yamlcompose import (  # noqa: F401 - re-exported
    _BOOL_RE,
    _FLOAT_RE,
    _IMPLICIT,
    _INT_RE,
    _LOADER,
    _NULL_RE,
    _SCALAR_TAGS,
    _T,
    BOOL,
    CACHE_DOCUMENTS,
    CACHE_MIN_CHARS,
    FLOAT,
    INT,
    MAP,
    MAX_ALIASES,
    MAX_BYTES,
    MAX_DEPTH,
    MAX_INT_DIGITS,
    MAX_NODES,
    MAX_VALUES_ENV,
    NULL,
    REPARSE_CHARS,
    SEQ,
    STR,
    CParser,
    YamlPath,
    _Counting,
    _line,
    _Loader,
    _Refused,
    _too_many_values,
    max_values,
)

_PARSED: dict[tuple[str, str, int], LoadedYaml] = {}  # (file, text, value limit) -> parsed, see loads_yaml


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


def _show_tag(tag: str) -> str:
    return "!!" + tag[len(_T) :] if tag.startswith(_T) else tag


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
            self.add(
                _line(node),
                path,
                f"unsupported tag {_show_tag(node.tag)} on {_kind(node)}; expected plain data without tags",
            )
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
                self.add(
                    _line(key_node), path + (key,), f"duplicate key {key!r} (first at line {first[key]})"
                )
                continue
            first[key] = self.lines[path + (key,)] = _line(key_node)
            out[key] = self.build(value_node, path + (key,))
        return out

    def key(self, node: Node, path: YamlPath) -> str | None:
        if not isinstance(node, ScalarNode):
            self.add(_line(node), path, f"expected a plain key (a name or number), found {_kind(node)}")
            return None
        if node.tag not in _SCALAR_TAGS:
            self.add(
                _line(node),
                path + (node.value,),
                f"unsupported tag {_show_tag(node.tag)} on a key; expected plain data without tags",
            )
            return None
        if node.value == "<<" and not node.style:  # plain: None (Python parser) or "" (libyaml)
            self.add(
                _line(node),
                path + ("<<",),
                "merge keys ('<<') are not supported (YAML 1.2 has none); "
                "write the keys out or use a plain alias (*name)",
            )
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
                self.add(
                    _line(node),
                    path,
                    f"number too large: an integer of {len(digits)} digits (at "
                    f"most {MAX_INT_DIGITS}); write it as a float with an exponent",
                )
                return None
            return (-1 if text.startswith("-") else 1) * int(digits, base)
        if tag == FLOAT and _FLOAT_RE.match(text):
            lower = text.lower()
            if lower.endswith(".inf"):
                return -math.inf if lower.startswith("-") else math.inf
            return math.nan if lower == ".nan" else float(text)
        if tag in _SCALAR_TAGS:
            self.add(
                _line(node), path, f"expected {_SCALAR_TAGS[tag]} after {_show_tag(tag)}, found {text[:40]!r}"
            )
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
            found = (
                "an empty document" if empty else "a list" if isinstance(node, SequenceNode) else "plain text"
            )
            raise fail(
                1 if empty else _line(node),
                f"expected a mapping at top level (key: value lines), found {found}"
                " (is this a crashstudy model or study file?)",
            )  # nothing of a foreign file is quoted
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


def not_regular(mode: int, expected: str = "a YAML file") -> str:
    """Why a file of ``mode`` (``os.stat``) cannot be read as ``expected`` ("" for a regular file)."""
    kind = file_kind(mode)
    if not kind:
        return ""
    if kind == "a folder":
        return f"is a directory, expected {expected}"
    return f"not a regular file: it is {kind}; expected {expected}"


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
    if not reason and raw is None:  # a non-blocking read with nothing to give: /proc/kmsg, a device, a pipe
        reason = (
            "cannot read the file: it gives no data without waiting (a kernel or device file such as "
            "/proc/kmsg?); expected a YAML file"
        )
    if reason:
        raise InputError([Problem(file, None, "", reason)])
    assert raw is not None
    if len(raw) > MAX_BYTES:
        reason = f"document too large: more than {MAX_BYTES:,} bytes (20 MB)"
    else:
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            line = raw.count(b"\n", 0, exc.start) + 1
            reason = (
                f"not UTF-8 text: byte 0x{raw[exc.start]:02x} on line {line} cannot be decoded; "
                "save the file as UTF-8"
            )
    raise InputError([Problem(file, None, "", reason)])
