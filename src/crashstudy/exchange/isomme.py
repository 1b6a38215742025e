"""ISO-MME (ISO/TS 13499) test data: the one reader and the one writer (docs/isomme.md).

A test is a folder ``<test>/<test>.mme`` (test header) with ``Channel/<test>.chn`` (the channel list) and
``Channel/<test>.001 ...`` (one channel each: header lines, then one value a line). It is read from the
``.mme`` file, its folder or a ``.zip`` of it. Header lines are ``name : value`` split at the first colon
(names padded to 28 columns when written); ``NOVALUE`` is missing (NaN in the data). Text is UTF-8 (with or
without BOM), else cp1252, else ISO-8859-1; line ends LF or CRLF. Time is implicit (``Time of first
sample`` + k ``Sampling interval``) or explicit (``Reference channel : explicit`` and ``Reference channel
name`` the code of the channel that holds the times).

Nothing here knows the model: units are converted by :mod:`crashstudy.exchange.testcurve`.
"""

from __future__ import annotations

import fnmatch
import io
import zipfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

import numpy as np

from crashstudy.safefs import PlantedEntryError, open_regular

FILE_MAX = 256 * 2**20  #: bytes of one file of a test at most (a channel of ~10^7 samples)
NOVALUE = "NOVALUE"
NAME_WIDTH = 28  #: header names are padded to this many columns
CODE_LENGTH = 16


class IsoMmeError(ValueError):
    """An ISO-MME test cannot be used: ``where`` (file, and line when known), ``field`` (the part of the
    data block it concerns: path, channel or unit) and what was expected."""

    data_file = True

    def __init__(self, where: str, message: str, field: str = "path") -> None:
        super().__init__(f"{where}: {message}" if where else message)
        self.where, self.message, self.field = where, message, field


def decode(raw: bytes) -> str:
    """Text of an ISO-MME file: UTF-8 (a BOM dropped), else cp1252, else ISO-8859-1 (which decodes
    every byte: the five bytes cp1252 leaves undefined)."""
    if raw.startswith(b"\xef\xbb\xbf"):
        return raw[3:].decode("utf-8", errors="replace")
    for enc in ("utf-8", "cp1252"):
        try:
            return raw.decode(enc)
        except UnicodeDecodeError:
            pass
    return raw.decode("iso-8859-1")


def parse_header(text: str, where: str) -> tuple[dict[str, str], int, list[str]]:
    """(header name -> value, index of the first data line, the lines) of a file: header lines are
    ``name : value`` up to the first line without a colon (an ``.mme`` or ``.chn`` file is header only)."""
    lines = text.splitlines()
    header: dict[str, str] = {}
    k = 0
    for k, line in enumerate(lines):  # noqa: B007 (k is the first data line after the loop)
        if ":" not in line:
            if line.strip():
                break
            continue
        name, value = line.split(":", 1)
        header.setdefault(name.strip(), value.strip())
    else:
        k = len(lines)
    return header, k, lines


def number(header: dict[str, str], name: str, where: str) -> float | None:
    text = header.get(name)
    if text is None or text.upper() == NOVALUE or not text:
        return None
    try:
        return float(text)
    except ValueError:
        raise IsoMmeError(where, f"header {name!r} is {text[:40]!r}; expected a number") from None


@dataclass
class ChannelFile:
    """One channel of a test: its header and values (NaN where ``NOVALUE``)."""

    where: str  # how messages name the file
    code: str
    header: dict[str, str]
    values: np.ndarray
    first_line: int  # 1-based line of the first value

    @property
    def unit(self) -> str:
        return self.header.get("Unit", "")

    @property
    def name(self) -> str:
        return self.header.get("Name of the channel", "")


@dataclass
class Test:
    """An ISO-MME test as read: its header, and its channels by file name (read on demand)."""

    where: str
    header: dict[str, str]
    codes: dict[str, str]  # channel file (relative to the test) -> channel code
    _read: object = field(repr=False)  # (relative path) -> bytes
    _cache: dict[str, ChannelFile] = field(default_factory=dict, repr=False)

    def channel(self, path: str) -> ChannelFile:
        if path not in self._cache:
            self._cache[path] = read_channel(self._read(path), f"{self.where}: {path}")  # type: ignore[operator]
        return self._cache[path]

    def find(self, pattern: str) -> ChannelFile:
        """The one channel whose code matches ``pattern`` (16 characters, ``?`` any one character)."""
        if len(pattern) != CODE_LENGTH or any(c in pattern for c in "*[]"):
            raise IsoMmeError(
                self.where,
                f"channel {pattern!r}: expected a 16-character channel code, '?' matching any one character",
                "channel",
            )
        hits = [p for p, code in self.codes.items() if fnmatch.fnmatchcase(code.upper(), pattern.upper())]
        if len(hits) != 1:
            listed = ", ".join(sorted(self.codes[p] for p in hits) if hits else sorted(self.codes.values()))
            what = f"{len(hits)} channels match" if hits else "no channel matches; the test has"
            raise IsoMmeError(
                self.where,
                f"channel {pattern!r}: {what}: {listed[:400]} (give a code that matches exactly one)",
                "channel",
            )
        return self.channel(hits[0])

    def times(self, ch: ChannelFile) -> np.ndarray:
        """The time of each sample of ``ch`` [s]: implicit, or its explicit reference channel's values."""
        n = len(ch.values)
        if ch.header.get("Reference channel", "implicit").strip().lower() == "explicit":
            ref = ch.header.get("Reference channel name", "")
            t = self.find(ref).values if len(ref) == CODE_LENGTH else None
            if t is None or len(t) != n:
                raise IsoMmeError(
                    ch.where,
                    f"explicit time: 'Reference channel name' {ref[:40]!r} must be the "
                    f"code of a channel of {n} samples",
                )
            return t
        t0 = number(ch.header, "Time of first sample", ch.where)
        dt = number(ch.header, "Sampling interval", ch.where)
        if t0 is None or dt is None or not dt > 0:
            raise IsoMmeError(
                ch.where, "implicit time needs 'Time of first sample' and a 'Sampling interval' > 0"
            )
        return t0 + dt * np.arange(n)


def read_channel(raw: bytes, where: str) -> ChannelFile:
    header, first, lines = parse_header(decode(raw), where)
    values = []
    for k in range(first, len(lines)):
        text = lines[k].strip()
        if not text:
            continue
        if text.upper() == NOVALUE:
            values.append(np.nan)
            continue
        try:
            values.append(float(text))
        except ValueError:
            raise IsoMmeError(
                f"{where}, line {k + 1}", f"expected a number or NOVALUE, got {text[:20]!r}"
            ) from None
    n = number(header, "Number of samples", where)
    if n is not None and n != len(values):
        raise IsoMmeError(where, f"'Number of samples' is {n:g}, the file has {len(values)} values")
    code = header.get("Channel code", "")
    return ChannelFile(where, code, header, np.array(values, dtype=float), first + 1)


def _reader_of(path: Path) -> tuple[object, str, str]:
    """(read(relative path) -> bytes, the .mme path relative to the root, how messages name the test)."""
    where = str(path)

    def limited(p: Path) -> bytes:
        try:
            with open_regular(p, FILE_MAX, what=str(p), follow=True) as fh:
                return fh.read()
        except FileNotFoundError:
            raise IsoMmeError(str(p), "no such file (a file of the ISO-MME test)") from None
        except PlantedEntryError as exc:
            raise IsoMmeError("", str(exc)) from None

    if path.suffix.lower() == ".zip":
        raw = limited(path)
        try:
            zf = zipfile.ZipFile(io.BytesIO(raw))
        except zipfile.BadZipFile:
            raise IsoMmeError(where, "not a zip archive; expected a .zip of an ISO-MME test folder") from None
        names = {n.lower(): n for n in zf.namelist()}
        mmes = [n for n in zf.namelist() if n.lower().endswith(".mme")]

        def from_zip(rel: str) -> bytes:
            name = names.get(rel.lower())
            if name is None:
                raise IsoMmeError(f"{where}: {rel}", "not in the archive (a file of the ISO-MME test)")
            if zf.getinfo(name).file_size > FILE_MAX:
                raise IsoMmeError(f"{where}: {rel}", f"more than {FILE_MAX} bytes")
            return zf.read(name)

        if len(mmes) != 1:
            raise IsoMmeError(where, f"expected one .mme file in the archive, found {len(mmes)}")
        return from_zip, mmes[0], where
    if path.is_dir():
        mmes = sorted(p.name for p in path.iterdir() if p.name.lower().endswith(".mme"))
        if len(mmes) != 1:
            raise IsoMmeError(where, f"expected a folder with one .mme file, found {len(mmes)}")
        root, mme = path, mmes[0]
    else:
        root, mme = path.parent, path.name

    def from_dir(rel: str) -> bytes:
        p = root.joinpath(*PurePosixPath(rel).parts)
        if not p.exists() and p.parent.exists():  # the case of a name may differ (CHANNEL/, .CHN)
            p = next((q for q in p.parent.iterdir() if q.name.lower() == p.name.lower()), p)
        if not p.parent.exists() and p.parent.parent.exists():
            d = next((q for q in p.parent.parent.iterdir() if q.name.lower() == p.parent.name.lower()), None)
            p = d / p.name if d is not None else p
        return limited(p)

    return from_dir, mme, where


def read_test(path: Path) -> Test:
    """The test at ``path`` (its ``.mme`` file, its folder or a ``.zip``); its channel files are the ones
    ``Channel/<test>.chn`` lists (``Name of channel NNN : CODE / name`` -> ``Channel/<test>.NNN``), read
    when a channel is asked for. File and folder names match without regard to case."""
    read, mme, where = _reader_of(Path(path))
    header, _, _ = parse_header(decode(read(mme)), where)  # type: ignore[operator]
    stem = PurePosixPath(mme).stem
    base = str(PurePosixPath(mme).parent / "Channel")
    base = "Channel" if base.startswith(".") else base
    chn, _, _ = parse_header(decode(read(f"{base}/{stem}.chn")), f"{where}: {base}/{stem}.chn")  # type: ignore[operator]
    codes: dict[str, str] = {}
    count = number(chn, "Number of channels", f"{where}: {base}/{stem}.chn") or 0
    for k in range(1, int(count) + 1):
        entry = chn.get(f"Name of channel {k:03d}", "")
        code = entry.split("/", 1)[0].strip()
        codes[f"{base}/{stem}.{k:03d}"] = code
    if not codes:
        raise IsoMmeError(
            f"{where}: {base}/{stem}.chn",
            "expected 'Number of channels' and 'Name of channel 001 : CODE / name' lines",
        )
    return Test(where, header, codes, read)


# --- writing -------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class OutChannel:
    """A channel to write: code (16 characters), name, SI unit, first time, interval [s], values."""

    code: str
    name: str
    unit: str
    t0: float
    dt: float
    values: np.ndarray
    extra: tuple[tuple[str, str], ...] = ()  # further header lines (name, value)


def fmt(value: float) -> str:
    """A sample as written: 12 significant digits, ``NOVALUE`` for NaN."""
    return NOVALUE if not np.isfinite(value) else f"{value:.12g}"


def header_text(items: list[tuple[str, str]]) -> str:
    return "".join(f"{name:<{NAME_WIDTH}}:{value}\r\n" for name, value in items)


def mme_files(test: str, header: list[tuple[str, str]], channels: list[OutChannel]) -> dict[str, bytes]:
    """The files of one test (relative path -> bytes, UTF-8, CRLF line ends as the standard's examples)."""
    files = {
        f"{test}.mme": header_text(
            [("Data format edition number", "1.6"), *header, ("Number of channels", str(len(channels)))]
        ).encode()
    }
    chn = [("Instrumentation standard", "ISO 6487"), ("Number of channels", str(len(channels)))]
    chn += [(f"Name of channel {k:03d}", f"{c.code} / {c.name}") for k, c in enumerate(channels, 1)]
    files[f"Channel/{test}.chn"] = header_text(chn).encode()
    for k, c in enumerate(channels, 1):
        head = [
            ("Instrumentation standard", "ISO 6487"),
            ("Data format edition number", "1.6"),
            ("Channel code", c.code),
            ("Name of the channel", c.name),
            *c.extra,
            ("Unit", c.unit),
            ("Reference channel", "implicit"),
            ("Time of first sample", fmt(c.t0)),
            ("Sampling interval", fmt(c.dt)),
            ("Number of samples", str(len(c.values))),
            ("Data source", "calculated"),
        ]
        body = "".join(fmt(v) + "\r\n" for v in np.asarray(c.values, dtype=float))
        files[f"Channel/{test}.{k:03d}"] = (header_text(head) + body).encode()
    return files
