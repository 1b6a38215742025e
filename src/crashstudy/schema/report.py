"""Turn validation failures into :class:`~crashstudy.errors.Problem` lists with file and line."""

from __future__ import annotations

import difflib
import typing
from typing import Any

from pydantic import BaseModel, ValidationError

from crashstudy.errors import Problem
from crashstudy.schema.yamlio import LoadedYaml
from crashstudy.vocabulary.materials import MATERIAL_CODES

Path = tuple[str | int, ...]


def data_path(data: Any, loc: tuple[Any, ...]) -> Path:
    """Keep only the parts of a pydantic ``loc`` that address the document (drop union tags)."""
    out: list[str | int] = []
    cur = data
    for part in loc:
        if isinstance(cur, dict) and part in cur:
            out.append(part)
            cur = cur[part]
        elif isinstance(cur, list) and isinstance(part, int) and 0 <= part < len(cur):
            out.append(part)
            cur = cur[part]
        elif isinstance(cur, dict) and isinstance(part, str) and not _looks_like_tag(part):
            out.append(part)  # a missing key: keep it so the message names it
            cur = None
        # else: a union/discriminator tag such as 'linear_elastic' or 'list[float]': skip
    return tuple(out)


def _looks_like_tag(part: str) -> bool:
    return any(ch in part for ch in "[]()") or part in {
        *MATERIAL_CODES,
        "bool",
        "float",
        "int",
        "str",
        "list",
        "dict",
        "none",
        "literal",
        "function-after",
    }


def dotted(path: Path) -> str:
    return ".".join(str(p) for p in path)


def _fields_at(root: type[BaseModel], data: Any, path: Path) -> list[str] | None:
    """Field names allowed in the mapping at ``path`` (for 'did you mean' hints), if known."""
    cls: Any = root
    cur = data
    for part in path:
        if isinstance(cur, dict):
            cur = cur.get(part)
        elif isinstance(cur, list) and isinstance(part, int) and part < len(cur):
            cur = cur[part]
        cls = _step(cls, part, cur)
        if cls is None:
            return None
    if isinstance(cls, type) and issubclass(cls, BaseModel):
        return list(cls.model_fields)
    return None


def _unwrap(tp: Any, value: Any) -> Any:
    """Strip Annotated/Optional/Union down to a BaseModel (choosing by 'type' for materials)."""
    while True:
        origin = typing.get_origin(tp)
        if origin is typing.Annotated:
            tp = typing.get_args(tp)[0]
            continue
        if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
            models = [a for a in typing.get_args(tp) if isinstance(a, type) and issubclass(a, BaseModel)]
            if isinstance(value, dict) and "type" in value:
                for mcls in models:
                    f = mcls.model_fields.get("type")
                    if f is not None and value["type"] in typing.get_args(f.annotation):
                        return mcls
            if len(models) == 1:
                return models[0]
            others = [a for a in typing.get_args(tp) if a is not type(None)]
            if len(others) == 1:
                tp = others[0]
                continue
            return None
        return tp


def _step(cls: Any, part: str | int, value: Any) -> Any:
    if isinstance(cls, type) and issubclass(cls, BaseModel):
        f = cls.model_fields.get(str(part))
        return None if f is None else _unwrap(f.annotation, value)
    origin = typing.get_origin(cls)
    if origin in (list, dict):
        args = typing.get_args(cls)
        return _unwrap(args[-1], value)
    return None


def _message(err: Any, allowed: list[str] | None) -> str:
    kind = err["type"]
    if kind == "missing":
        return f"missing required field {err['loc'][-1]!r}"
    if kind == "extra_forbidden":
        key = err["loc"][-1]
        hint = ""
        if allowed:
            close = difflib.get_close_matches(str(key), allowed, n=3)
            hint = (
                f"; did you mean {' or '.join(repr(c) for c in close)}?"
                if close
                else f"; expected one of {allowed}"
            )
        return f"unknown key {key!r}{hint}"
    msg = str(err["msg"])
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, ") :]
    if msg.startswith("Input should be "):
        msg = "expected " + msg[len("Input should be ") :]
    if msg.startswith("Input tag "):
        msg = msg.replace("Input tag", "material type").replace(
            "found using 'type' does not match any of the expected tags:", "is unknown; expected one of"
        )
    if "input" in err and kind not in ("missing",) and not isinstance(err["input"], (dict, list)):
        msg += f" (got {err['input']!r})"
    return msg


MAX_HINTED = (
    100  #: problems of a file given a "did you mean" hint (more are never shown: errors.InputError.format)
)


def pydantic_problems(
    exc: ValidationError, doc: LoadedYaml, root: type[BaseModel], prefix: Path = ()
) -> list[Problem]:
    """Problems of a pydantic error, located in ``doc`` (``prefix``: where the validated data sits)."""
    data = doc.data
    for p in prefix:
        data = data[p]
    problems: list[Problem] = []
    seen: set[tuple[Path, str]] = set()
    for err in exc.errors(include_url=False):
        path = data_path(data, tuple(err["loc"]))
        parent = path[:-1] if err["type"] in ("extra_forbidden", "missing") else path
        hinted = (
            err["type"] == "extra_forbidden" and len(problems) < MAX_HINTED
        )  # difflib is slow: the shown ones
        allowed = _fields_at(root, data, parent) if hinted else None
        msg = _message(err, allowed)
        if (path, msg) in seen:
            continue
        seen.add((path, msg))
        line = doc.line_of(prefix + path)
        problems.append(Problem(doc.file, line, dotted(prefix + path), msg))
    return problems


def located(doc: LoadedYaml, found: list[tuple[Path, str]], prefix: Path = ()) -> list[Problem]:
    """Problems from ``(path, message)`` pairs, located in ``doc``."""
    return [Problem(doc.file, doc.line_of(prefix + p), dotted(prefix + p), msg) for p, msg in found]
