"""``crashstudy report DIR``: the page's content against closed-form numbers of a tiny study
(tests/report_study.py), the output policy, sampling above the documented sizes, and the sections of the
files other commands write (sensitivity.csv, correlation.csv, optimum.yaml + history.csv, calibrated.yaml).
The page in a real browser: tests/test_report_browser.py."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

import report_study as rs
from crashstudy.cli.main import main


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return rs.write_and_run(tmp_path_factory.mktemp("report"))


def _figures(html: str) -> list[dict]:
    return [
        json.loads(m.replace("<\\/", "</"))
        for m in re.findall(r'<script type="application/json" id="cs-fig-\d+">(.*?)</script>', html, re.S)
    ]


def _table(html: str) -> dict:
    m = re.search(r'<script type="application/json" id="cs-table-data">(.*?)</script>', html, re.S)
    assert m
    return json.loads(m.group(1).replace("<\\/", "</"))


def _section(html: str, anchor: str) -> str:
    m = re.search(rf'<section id="{anchor}">(.*?)</section>', html, re.S)
    assert m, f"no section {anchor}"
    return m.group(1)


def test_report_page_shows_the_study_with_closed_form_numbers(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "r.html"
    assert main(["report", str(folder), "-o", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    html = out.read_text()
    # one inlined plotly.js, nothing referenced outside the file
    assert html.count("plotly.js v") == 1 and len(html) > 3_000_000
    page = re.sub(
        r"<script>/\*\*\n\* plotly\.js v.*?</script>", "", html, count=1, flags=re.S
    )  # the library's text
    assert len(page) < len(html) - 3_000_000
    assert not re.search(r'\b(src|href)\s*=\s*["\']?(https?:)?//', page)
    assert not re.search(r"<(script|link|img|iframe)[^>]*\b(src|href)=", page)
    # study: axes and their ranges with units, counts by status
    study = _section(html, "study")
    assert "nodes.body.mass" in study and "<td>800</td><td>1000</td>" in study and "m/s" in study
    fails = [rs.fails(m, k) for m in rs.MASSES for k in rs.STIFFNESS]
    assert f"ok: {fails.count(False)}, failed: {fails.count(True)}" in study
    # failed variants with their reasons: exactly the closed-form ones
    failures = _section(html, "failures")
    listed = [int(v) for v in re.findall(r"<tr><td>(\d+)</td>", failures)]
    assert listed == [i for i, f in enumerate(fails) if f] == [2, 5]
    assert failures.count('<td class="t">fixed dt=0.0001 is above the critical step') == 2
    assert "<li>2 x fixed dt=# is above the critical step dt_crit=# (node body / spring s#)</li>" in failures
    # the table: one row per variant, units in the columns
    table = _table(html)
    assert [r[0] for r in table["rows"]] == list(range(6))
    cols = {c["name"]: c["unit"] for c in table["columns"]}
    assert (
        cols["impact_velocity"] == "m/s"
        and cols["peak_deceleration_g.body"] == "g"
        and cols["hic15.body"] == "-"
    )
    # parallel coordinates: green (1) where peak deceleration F / (m g) <= 12 g (optimize constraint) and the
    # criteria are within their usual limits (they are: at most 13 g here), red (0) where not
    figs = _figures(html)
    par = next(f for f in figs if f["data"][0]["type"] == "parcoords")
    ok = [
        (m, v) for m in rs.MASSES for v, k in zip(rs.SPEEDS, rs.STIFFNESS, strict=True) if not rs.fails(m, k)
    ]
    expected = [1 if rs.PLATEAU / (m * rs.G) <= rs.CONSTRAINT_G else 0 for m, _ in ok]
    assert par["data"][0]["line"]["color"] == expected == [0, 0, 1, 1]
    dims = {d["label"].replace("<br>", ""): d["values"] for d in par["data"][0]["dimensions"]}
    np.testing.assert_allclose(
        dims["peak_deceleration_g.body [g]"], [rs.PLATEAU / (m * rs.G) for m, _ in ok], rtol=1e-4
    )
    # an anthill figure per response, one panel per axis (x axis titles carry the units)
    hill = next(f for f in figs if f["layout"].get("title", {}).get("text") == "peak_deceleration_g.body")
    assert [t["xaxis"] for t in hill["data"]] == ["x", "x2", "x3"]  # mass, speed, stiffness
    assert hill["layout"]["xaxis2"]["title"]["text"] == "impact_velocity [m/s]"
    assert [s["y0"] for s in hill["layout"]["shapes"]] == [rs.CONSTRAINT_G] * 3
    # criteria against their usual limits, with the standard the limit comes from
    crit = _section(html, "criteria")
    assert "clip3ms" in crit and "FMVSS 208 S6.3" in crit and "Euro NCAP" in crit and "0 of 4" in crit
    # histories: worst (800 kg, highest peak), best (1000 kg) and the baseline; deceleration plateau F / m in g
    hist = next(f for f in figs if f["layout"].get("xaxis", {}).get("title", {}).get("text") == "time [ms]")
    names = [t["name"] for t in hist["data"]]
    assert names[0].startswith("variant 0 (worst)") and names[1].startswith("variant 3 (best)")
    peak = max(v for v in hist["data"][1]["y"] if v is not None)
    assert peak == pytest.approx(rs.PLATEAU / (1000 * rs.G), rel=0.03)  # CFC 60 filtered plateau


def test_report_refuses_to_overwrite_and_bad_choices(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "r.html"
    out.write_text("mine")
    assert main(["report", str(folder), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(out) in err and "--force" in err and "Traceback" not in err
    assert out.read_text() == "mine"
    assert main(["report", str(folder), "-o", str(tmp_path / "s.html"), "--variants", "0,9"]) == 2
    err = capsys.readouterr().err
    assert "--variants" in err and "'9'" in err and "0 to 5" in err
    assert main(["report", str(folder), "-o", str(tmp_path / "s.html"), "--responses", "nope"]) == 2
    assert "'nope'" in capsys.readouterr().err
    assert main(["report", str(folder), "-o", str(tmp_path / "s.html"), "--limits", "nope<=1"]) == 2
    assert "--limits: 'nope<=1': 'nope' is not a summary column" in capsys.readouterr().err
    assert main(["report", str(folder), "-o", str(folder / "summary.csv")]) == 2
    assert main(["report", str(tmp_path / "missing")]) == 2
    assert not (tmp_path / "s.html").exists()
    # chosen by name and number; a failed variant is drawn and said to have failed
    assert main(["report", str(folder), "-o", str(tmp_path / "v.html"), "--variants", "best,2"]) == 0
    hist = [
        f
        for f in _figures((tmp_path / "v.html").read_text())
        if f["layout"].get("xaxis", {}).get("title", {}).get("text") == "time [ms]"
    ][0]
    assert [t["name"].split(",")[0] for t in hist["data"]] == ["variant 3 (best)", "variant 2"]
    assert hist["data"][1]["name"].endswith("FAILED")


def test_report_limits_of_the_user_join_the_checks(folder: Path, tmp_path: Path) -> None:
    # crush m v^2 / (2 F) + 0.005 m: 0.105 / 0.405 m at 800 kg, 0.13 / 0.505 m at 1000 kg (5 / 10 m/s)
    out = tmp_path / "r.html"
    assert main(["report", str(folder), "-o", str(out), "--limits", "max_crush.s1<=0.3"]) == 0
    par = next(f for f in _figures(out.read_text()) if f["data"][0]["type"] == "parcoords")
    ok = [
        (m, v) for m in rs.MASSES for v, k in zip(rs.SPEEDS, rs.STIFFNESS, strict=True) if not rs.fails(m, k)
    ]
    crush_ok = [m * v * v / (2 * rs.PLATEAU) + 0.005 <= 0.3 for m, v in ok]
    peak_ok = [rs.PLATEAU / (m * rs.G) <= rs.CONSTRAINT_G for m, _ in ok]
    assert (
        par["data"][0]["line"]["color"]
        == [int(a and b) for a, b in zip(crush_ok, peak_ok, strict=True)]
        == [0, 0, 1, 0]
    )


def test_report_samples_above_the_documented_sizes(
    folder: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from crashstudy.analysis import report

    monkeypatch.setattr(report, "SCATTER_MAX", 3)
    monkeypatch.setattr(report, "TABLE_MAX", 5)
    out = tmp_path / "r.html"
    assert main(["report", str(folder), "-o", str(out)]) == 0
    html = out.read_text()
    rows = [r[0] for r in _table(html)["rows"]]
    assert len(rows) == 5 and {2, 5, 0, 3} <= set(rows)  # failed (2, 5), worst (0) and best (3) always kept
    par = next(f for f in _figures(html) if f["data"][0]["type"] == "parcoords")
    assert len(par["data"][0]["line"]["color"]) == 3
    assert "a random sample of 3 of 4 ok variants" in html and "a sample of 5 of 6 variants" in html


def test_report_sections_of_derived_files(folder: Path, tmp_path: Path) -> None:
    work = tmp_path / "res"
    shutil.copytree(folder, work)
    assert main(["sensitivity", str(work), "--metric", "peak_deceleration_g.body"]) == 0
    (work / "correlation.csv").write_text(
        "variant,nodes.body.mass,impact_velocity,R,Z,EP,EM,ES,grade\n"
        "0,800,5,0.61,0.5,0.7,0.7,0.7,fair\n3,1000,5,0.93,0.9,1,0.9,0.95,excellent\n"
    )
    (work / "optimum.yaml").write_text(
        "variables: {nodes.body.mass: 1000.0}\nobjective: {max_crush.s1: 0.13}\nfeasible: true\n"
    )
    (work / "history.csv").write_text(
        "nodes.body.mass,status,max_crush.s1,feasible,score\n800,ok,0.2,False,1e15\n"
        "900,ok,0.15,True,0.15\n1000,ok,0.13,True,0.13\n"
    )
    (tmp_path / "test.csv").write_text("time,value\n0.0,0.0\n0.01,9.5\n0.05,10.0\n")
    out = tmp_path / "r.html"
    assert main(["report", str(work), "-o", str(out), "--test", str(tmp_path / "test.csv")]) == 0
    html = out.read_text()
    test_curve = [t for f in _figures(html) for t in f["data"] if t.get("name") == "test"]
    assert [(c["x"], c["y"]) for c in test_curve] == [([0.0, 10.0, 50.0], [0.0, 9.5, 10.0])]  # time in ms
    (tmp_path / "bad.csv").write_text("t,v\n1,2\n")
    assert (
        main(["report", str(work), "-o", str(tmp_path / "b.html"), "--test", str(tmp_path / "bad.csv")]) == 2
    )
    sens = _section(html, "sensitivity")
    # mass alone lowers the peak (F / m): Spearman -1 among the ok variants, impact speed 0
    fig = next(f for f in _figures(html) if "sensitivity of" in f["layout"]["title"]["text"])
    spearman = next(t for t in fig["data"] if t["name"] == "spearman")
    assert dict(zip(spearman["y"], spearman["x"], strict=True))["nodes.body.mass"] == pytest.approx(
        -1.0, abs=1e-6
    )
    assert "confidence" in sens
    corr = _section(html, "correlation")
    assert corr.index("<td>3</td>") < corr.index("<td>0</td>") and "excellent" in corr  # best R first
    hist = [
        f for f in _figures(html) if f["layout"].get("xaxis", {}).get("title", {}).get("text") == "time [ms]"
    ][0]
    assert "R 0.930 (excellent)" in hist["data"][1]["name"]
    opt = next(f for f in _figures(html) if f["layout"]["title"]["text"].startswith("optimisation history"))
    assert opt["data"][1]["y"] == [None, 0.15, 0.13]  # best feasible so far
    assert "3 candidates, 2 feasible" in opt["layout"]["title"]["text"]
    (work / "history.csv").write_text("no,feasible column\n1,2\n")
    assert main(["report", str(work), "-o", str(tmp_path / "bad.html")]) == 2
