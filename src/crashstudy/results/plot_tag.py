"""The mark of a figure written by ``crashstudy plot`` (a PNG text chunk naming the result it shows), so that
a new run may remove the stale plots in a result folder's ``plots/`` and never another file.
"""

from __future__ import annotations

import struct
from pathlib import Path

PLOT_TAG = "crashstudy-plot-of"  #: PNG text key naming the result a figure of ``crashstudy plot`` shows


def is_crashstudy_plot(path: Path) -> bool:
    """Whether the PNG at ``path`` was written by ``crashstudy plot`` (it carries :data:`PLOT_TAG`).

    Reads the PNG's chunks up to the image data; a file that is not a PNG is not ours."""
    try:
        with open(path, "rb") as fh:
            if fh.read(8) != b"\x89PNG\r\n\x1a\n":
                return False
            while True:
                head = fh.read(8)
                if len(head) < 8:
                    return False
                size, kind = struct.unpack(">I4s", head)
                if kind in (b"IDAT", b"IEND") or size > 1 << 20:
                    return False
                body = fh.read(size + 4)[:size]
                if kind in (b"tEXt", b"iTXt") and body.split(b"\x00", 1)[0] == PLOT_TAG.encode():
                    return True
    except OSError:
        return False
