"""``crashstudy export SOURCE --dyna OUT.k`` and ``crashstudy import DECK -o MODEL.yaml`` (docs/dyna.md).

Arguments are parsed in :mod:`crashstudy.cli.exchange`; this module loads, converts and writes
through the one safe writer. Bad input raises :class:`InputError` (exit code 2).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from crashstudy.errors import InputError, Problem


def _refuse_existing(out: Path, force: bool, flag: str) -> None:
    if out.exists() and not force:
        raise InputError(
            [Problem(str(out), None, flag, "exists: pass --force to replace it, or choose another name")]
        )
    if out.is_dir():
        raise InputError([Problem(str(out), None, flag, "is a folder: expected a file name")])


def export_dyna(args: argparse.Namespace) -> int:
    """Write the LS-DYNA deck of a model, or of one variant of a study (``--variant``, default 0)."""
    from crashstudy.exchange.dyna_export import export_deck
    from crashstudy.schema import file_kind, parse_model
    from crashstudy.schema.yamlio import LoadedYaml, load_yaml

    out = Path(args.dyna)
    _refuse_existing(out, args.force, "--dyna")
    doc = load_yaml(args.source)
    if file_kind(doc.data) == "study":
        from crashstudy.study.plan import load_study
        from crashstudy.study.variant import variant_data

        plan = load_study(args.source)
        n = args.variant or 0
        data = variant_data(plan, args.source, n)
        mdoc = load_yaml(plan.model_file)
        lm = parse_model(LoadedYaml(data, mdoc.text, mdoc.file, mdoc.lines))
        what = f"variant {n} of {args.source}"
    else:
        if args.variant not in (None, 0):
            raise InputError(
                [
                    Problem(
                        args.source,
                        None,
                        "--variant",
                        "a model has one variant (0): --variant applies to a study file",
                    )
                ]
            )
        lm = parse_model(doc)
        what = args.source
    text, rounded = export_deck(lm.model, lm.doc)
    from crashstudy.safefs import write_text

    write_text(out, text)
    print(
        f"wrote {out}: LS-DYNA deck of {what} ({len(lm.model.nodes)} nodes, {len(lm.model.springs)} springs)"
    )
    if rounded:
        print(
            f"note: {len(rounded)} value(s) did not fit their fixed-width field exactly and were rounded:",
            *rounded[:20],
            sep="\n  ",
            file=sys.stderr,
        )
    return 0


def import_deck(args: argparse.Namespace) -> int:
    """Write the model file of an LS-DYNA deck (the subset ``export --dyna`` writes)."""
    import yaml

    from crashstudy.exchange.dyna_import import import_deck as read_model
    from crashstudy.safefs import write_text
    from crashstudy.schema import validate_model_data

    out = Path(args.output)
    _refuse_existing(out, args.force, "--output")
    data, notes = read_model(args.deck, args.skip_unsupported)
    _, found = validate_model_data(data)
    if found:
        from pydantic import ValidationError

        errs = (
            [(tuple(e["loc"]), e["msg"]) for e in found.errors()]
            if isinstance(found, ValidationError)
            else found
        )
        raise InputError(
            [
                Problem(args.deck, None, ".".join(map(str, loc)), f"{msg} (in the model read from the deck)")
                for loc, msg in errs
            ]
        )
    text = f"# imported from {Path(args.deck).name} by crashstudy import\n" + yaml.safe_dump(
        data, sort_keys=False, default_flow_style=None, width=110
    )
    write_text(out, text)
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    print(f"wrote {out}: {len(data['nodes'])} nodes, {len(data.get('springs', {}))} springs")
    return 0
