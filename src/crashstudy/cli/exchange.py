"""``crashstudy export`` and ``crashstudy import``: exchange with the crash world's formats.

This module owns only the command line (arguments and dispatch). The ISO-MME side lives in
:mod:`crashstudy.cli.isomme_cmd` (``export DIR --isomme OUT``), the LS-DYNA side in
:mod:`crashstudy.cli.dyna_cmd` (``export MODEL --dyna OUT.k`` and ``import DECK.k``).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import Any


def register(sub: Any) -> dict[str, Callable[[argparse.Namespace], int]]:
    ex = sub.add_parser(
        "export",
        help="write a model as an LS-DYNA deck (--dyna) or a result folder's histories "
        "as ISO-MME test folders (--isomme)",
    )
    ex.add_argument("source", help="a model or study file (with --dyna) or a result folder (with --isomme)")
    to = ex.add_mutually_exclusive_group(required=True)
    to.add_argument(
        "--dyna", metavar="OUT.k", help="LS-DYNA keyword deck of the model (or of one study variant)"
    )
    to.add_argument("--isomme", metavar="OUT", help="folder of ISO-MME tests, one per chosen variant")
    ex.add_argument("--variant", type=int, help="with --dyna and a study: the variant to export (default 0)")
    ex.add_argument("--variants", metavar="SEL", help="with --isomme: the variants to export (default all)")
    ex.add_argument("--force", action="store_true", help="replace an existing output")
    im = sub.add_parser("import", help="model file from an LS-DYNA deck of discrete elements")
    im.add_argument("deck", help="the keyword deck (.k, .key, .dyn)")
    im.add_argument("-o", "--output", required=True, help="the model file to write")
    im.add_argument(
        "--skip-unsupported", action="store_true", help="list and skip keywords with no model equivalent"
    )
    im.add_argument("--force", action="store_true", help="replace an existing model file")
    return {"export": _export, "import": _import}


def _export(args: argparse.Namespace) -> int:
    if args.dyna:
        from crashstudy.cli.dyna_cmd import export_dyna

        return export_dyna(args)
    from crashstudy.cli.isomme_cmd import export_isomme

    return export_isomme(args)


def _import(args: argparse.Namespace) -> int:
    from crashstudy.cli.dyna_cmd import import_deck

    return import_deck(args)
