"""``crashstudy export DIR --isomme OUT [--variants SEL]``: a result folder's histories as ISO-MME tests
(docs/isomme.md). One test folder per chosen variant, ``OUT/<study>-<variant>/``; read through the one
reader of result folders, written through the safe writer (each test's files staged, then renamed)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from crashstudy.errors import InputError, Problem


def export_isomme(args: argparse.Namespace) -> int:
    import yaml

    from crashstudy.exchange.isomme import mme_files
    from crashstudy.exchange.isomme_channels import parse_selection, variant_channels
    from crashstudy.results.reader import open_results
    from crashstudy.safefs import folder_lock, write_all

    where = str(args.source)
    try:
        res = open_results(args.source)
    except FileNotFoundError as exc:
        raise InputError(
            [Problem(where, None, "", f"{exc}; expected a result folder of crashstudy run or simulate")]
        ) from None
    ds = res.dataset
    numbers = [int(v) for v in ds["variant"].values]
    try:
        chosen = parse_selection(args.variants, max(numbers) + 1) if args.variants else numbers
    except ValueError as exc:
        raise InputError([Problem(where, None, "--variants", str(exc))]) from None
    missing = sorted(set(chosen) - set(numbers))
    if missing:
        raise InputError(
            [Problem(where, None, "--variants", f"variant(s) {missing[:8]} are not in these results")]
        )
    model = yaml.safe_load(str(ds.attrs.get("model_yaml", ""))) or {}
    study = yaml.safe_load(str(ds.attrs.get("study_yaml", ""))) or {}
    setting = study.get("set") or {} if isinstance(study, dict) else {}
    model.update({k: v for k, v in setting.items() if k in ("iso_mme", "metrics")})
    name = str(ds.attrs.get("study_name") or ds.attrs.get("model_name") or "crashstudy")
    free = [str(n) for n in _json_list(ds.attrs.get("free_nodes"))] or [str(n) for n in ds["node"].values]
    status = (
        res.summary_columns(["status"])["status"].astype(str).to_numpy()
    )  # manifest-checked, in variant order
    out = Path(args.isomme)
    if os.path.lexists(out) and not out.is_dir():
        raise InputError(
            [Problem(str(out), None, "--isomme", "is a file; expected a folder (new or of tests)")]
        )
    tests = {v: f"{name}-{v}" for v in chosen}
    existing = [t for t in tests.values() if os.path.lexists(out / t)]
    if existing and not args.force:
        raise InputError(
            [
                Problem(
                    str(out),
                    None,
                    "--isomme",
                    f"test folder(s) {', '.join(existing[:4])} exist; use "
                    "--force to replace them or choose another OUT",
                )
            ]
        )
    out.mkdir(parents=True, exist_ok=True)
    skipped: list[int] = []
    with folder_lock(out):
        for v, test in tests.items():
            k = numbers.index(v)
            if status[k] != "ok":
                skipped.append(v)
                continue
            header = [
                ("Laboratory name", "crashstudy (calculated)"),
                ("Laboratory test ref. number", test),
                ("Title", f"{name} variant {v}"),
                ("Data source", "calculated"),
                ("Comments", f"crashstudy export of {os.path.abspath(args.source)}"),
            ]
            files = mme_files(test, header, variant_channels(ds, k, model, free))
            (out / test / "Channel").mkdir(parents=True, exist_ok=True)
            write_all([(out / test / rel, lambda fh, b=data: fh.write(b)) for rel, data in files.items()])
    res.close()
    if skipped:
        print(f"skipped {len(skipped)} failed variant(s): {skipped[:10]}", file=sys.stderr)
    print(
        f"wrote {len(tests) - len(skipped)} ISO-MME test(s) to {out} ({name}-<variant>/{name}-<variant>.mme)"
    )
    return 0


def _json_list(text: object) -> list[object]:
    import json

    try:
        value = json.loads(str(text)) if text else []
    except ValueError:
        return []
    return value if isinstance(value, list) else []
