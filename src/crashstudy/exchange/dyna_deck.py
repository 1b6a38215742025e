"""Reading an LS-DYNA keyword deck into blocks: keyword lines, cards, ``$`` comments and ``*INCLUDE``.

A deck is text: ``*KEYWORD`` lines open blocks, ``$`` lines are comments, every other line is a card of
the open block. ``*INCLUDE`` names further decks (one file name per card), resolved relative to the
folder of the deck that names them; each is read once per include path (a file that includes itself,
directly or through others, is an error naming the chain). Only regular files are read (no device, no
FIFO), of at most :data:`MAX_BYTES`; nothing in a deck is ever executed. ``*END`` ends a file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from crashstudy.errors import InputError, Problem
from crashstudy.safefs import open_regular

MAX_BYTES = 256 * 2**20  #: largest deck file read
META = "$crashstudy:"


@dataclass(frozen=True)
class Card:
    """One card line and where it is (file as the user would name it, 1-based line)."""

    text: str
    file: str
    line: int


@dataclass
class Block:
    """One keyword occurrence: its name (upper case, options after a blank dropped) and its cards."""

    keyword: str
    file: str
    line: int
    cards: list[Card] = field(default_factory=list)

    def problem(self, message: str, card: Card | None = None, fld: str = "") -> Problem:
        where = card or self
        return Problem(where.file, where.line, f"*{self.keyword}" + (f" {fld}" if fld else ""), message)


@dataclass
class Deck:
    """Every block of a deck and its includes, in reading order, and the ``$crashstudy:`` text."""

    blocks: list[Block] = field(default_factory=list)
    meta: str = ""


def read_deck(path: str) -> Deck:
    """Read ``path`` and its includes; raises :class:`InputError` (missing include, include loop)."""
    deck = Deck()
    _read(Path(path), path, deck, ())
    return deck


def _display(p: Path, shown_parent: str) -> str:
    return str(Path(shown_parent).parent / p) if not p.is_absolute() else str(p)


def _read(path: Path, shown: str, deck: Deck, chain: tuple[Path, ...]) -> None:
    real = path.resolve()
    if real in chain:
        names = " -> ".join(p.name for p in (*chain, real))
        raise InputError(
            [Problem(shown, None, "*INCLUDE", f"include loop: {names}; a deck cannot include itself")]
        )
    with open_regular(path, MAX_BYTES, shown, follow=True) as fh:
        raw = fh.read()
    text = (
        raw.decode("utf-8", errors="replace")
        if not raw.startswith(b"\xef\xbb\xbf")
        else raw[3:].decode("utf-8", "replace")
    )
    block: Block | None = None
    for no, line in enumerate(text.splitlines(), start=1):
        line = line.rstrip("\r\n")
        if line.startswith(META) and not chain:
            deck.meta += line[len(META) + 1 :]
            continue
        if line.startswith("$") or not line.strip():
            continue
        if line.startswith("*"):
            name = line[1:].split()[0].upper() if line[1:].strip() else ""
            if block is not None and block.keyword == "INCLUDE":
                _include(block, deck, chain + (real,))
            if name == "END":
                return
            block = Block(name, shown, no)
            if name != "INCLUDE":
                deck.blocks.append(block)
            continue
        if block is None:
            raise InputError(
                [Problem(shown, no, "", "a card before the first keyword: a deck starts with *KEYWORD")]
            )
        block.cards.append(Card(line, shown, no))
    if block is not None and block.keyword == "INCLUDE":
        _include(block, deck, chain + (real,))


def _include(block: Block, deck: Deck, chain: tuple[Path, ...]) -> None:
    base = chain[-1].parent
    for c in block.cards:
        name = c.text.strip()
        target = Path(name) if Path(name).is_absolute() else base / name
        shown = _display(Path(name), c.file)
        if not target.exists():
            raise InputError(
                [
                    Problem(
                        c.file,
                        c.line,
                        "*INCLUDE",
                        f"included file {name!r} not found (looked for "
                        f"{target}); an include is relative to the deck that names it",
                    )
                ]
            )
        _read(target, shown, deck, chain)
