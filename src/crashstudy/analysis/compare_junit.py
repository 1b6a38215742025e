"""``crashstudy compare --junit``: a :class:`~crashstudy.analysis.compare.Comparison` as JUnit XML, for CI."""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import TYPE_CHECKING

from crashstudy.analysis.compare_inputs import JUNIT_LIST, JUNIT_SUITE, _xml_text
from crashstudy.safefs import replacing

if TYPE_CHECKING:
    from crashstudy.analysis.compare import Comparison


def junit(comp: Comparison, path: str | os.PathLike[str] | None = None) -> ET.ElementTree:
    """JUnit XML: one ``<testsuite name="crashstudy compare">``, one ``<testcase>`` per metric column
    (a ``<failure>`` lists the variants past tolerance, the worst first) and one each for
    ``status``, missing variants and new variants. Written to ``path`` when given."""
    cls = f"crashstudy.compare.{comp.study_name}" if comp.study_name else "crashstudy.compare"
    cases: list[ET.Element] = []

    def case(name: str, failure: str | None = None, body: str = "", out: str = "") -> None:
        tc = ET.Element("testcase", name=_xml_text(name), classname=_xml_text(cls), time="0")
        if failure is not None:
            f = ET.SubElement(tc, "failure", message=_xml_text(failure), type="regression")
            f.text = _xml_text(body)
        if out:
            ET.SubElement(tc, "system-out").text = _xml_text(out)
        cases.append(tc)

    for name in sorted([*comp.stats, *comp.missing_columns, *comp.extra_columns]):
        if name in comp.missing_columns:
            case(
                name,
                "metric column missing from the new result",
                f"the baseline has {name}; the new result has not",
            )
        elif name in comp.extra_columns:
            case(name, out=f"{name} is new: no baseline value to compare with")
        else:
            c = comp.stats[name]
            bad = c.failed
            tol = f"rtol={c.rtol:g}, atol={c.atol:g}"
            if not bad:
                case(
                    name,
                    out=f"{c.compared} variants within tolerance ({tol}); largest |rel diff| "
                    f"{c.max_rel_diff:.3e}",
                )
                continue
            top = comp.top(JUNIT_LIST, column=name, only_failed=True)
            lines = [
                f"variant {int(r['variant'])} ({comp._params(r)}): old {r['old']:.10g} new {r['new']:.10g} "
                f"(rel diff {r['rel_diff']:+.3e}, tolerance {r['tolerance']:.3g})"
                for _, r in top.iterrows()
            ]
            if bad > len(top):
                lines.append(f"... and {bad - len(top)} more")
            worst = top["rel_diff"].iloc[0]
            case(
                name,
                f"{bad} of {c.compared} variants moved past tolerance ({tol}); worst rel diff {worst:+.3e}",
                "\n".join(lines),
            )
    st = comp.status
    bad_st = st[~st["passed"]] if len(st) else st
    more = comp.n_status - len(st)  # a streamed comparison lists the first STATUS_KEPT status changes
    ok_lines = (
        [
            f"variant {int(r['variant'])} ({comp._params(r)}): {r['old']} -> {r['new']}"
            for _, r in st[st["passed"]].iterrows()
        ]
        if len(st)
        else []
    )
    bad_lines = [
        f"variant {int(r['variant'])} ({comp._params(r)}): {r['failure_reason']}"
        for _, r in bad_st.iterrows()
    ]
    if more:
        (bad_lines if comp.n_status_failures > len(bad_st) else ok_lines).append(
            f"... and {more} more status changes"
        )
    case(
        "status",
        f"{comp.status_failures} variants went from ok to failed" if comp.status_failures else None,
        "\n".join(bad_lines),
        "\n".join(ok_lines),
    )
    missing = [
        f"baseline variant {int(r['baseline_variant'])}: {comp._params(r)}"
        for _, r in comp.missing.iterrows()
    ]
    extra = [f"variant {int(r['variant'])}: {comp._params(r)}" for _, r in comp.extra.iterrows()]
    for lines, count in (
        (missing, comp.n_missing),
        (extra, comp.n_extra),
    ):  # a streamed comparison: the first ones
        if count > len(lines):
            lines.append(f"... and {count - len(lines)} more")
    case(
        "variants missing from the new result",
        f"{comp.n_missing} baseline variants are not in the new result" if comp.n_missing else None,
        "\n".join(missing),
    )
    case("variants only in the new result", None, out="\n".join(extra))
    if comp.damaged:
        case(
            "complete result folders",
            f"{len(comp.damaged)} result folders are damaged",
            "\n".join(comp.damaged),
        )

    failures = sum(1 for tc in cases if tc.find("failure") is not None)
    root = ET.Element(
        "testsuites", name=JUNIT_SUITE, tests=str(len(cases)), failures=str(failures), errors="0"
    )
    suite = ET.SubElement(
        root,
        "testsuite",
        name=JUNIT_SUITE,
        tests=str(len(cases)),
        failures=str(failures),
        errors="0",
        skipped="0",
        time="0",
    )
    props = ET.SubElement(suite, "properties")
    for k, v in (
        ("new", str(comp.new_dir)),
        ("baseline", str(comp.baseline_dir)),
        ("default_rtol", f"{comp.rtol:g}"),
        ("default_atol", f"{comp.atol:g}"),
    ):
        ET.SubElement(props, "property", name=k, value=_xml_text(v))
    suite.extend(cases)
    tree = ET.ElementTree(root)
    ET.indent(tree)
    if path is not None:
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        with replacing(p, mode="wb") as fh:  # the one writer: a link at p is replaced, never followed
            tree.write(fh, encoding="utf-8", xml_declaration=True)
    return tree
