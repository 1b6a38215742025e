"""``crashstudy report`` opened in a real browser: Debian's headless Chromium driven by playwright (one browser
for the module). No console errors, every figure drawn with a nonzero size, one table row per variant, the
failed variants in the failures section, no request for anything outside the file. Screenshots go to
tmp_path. Without /usr/bin/chromium the test is skipped, except in CI (``CI`` set), where it fails: .ci/run
installs Chromium."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import report_study as rs
from crashstudy.cli.main import main
from report_browser import CHROMIUM, launch, open_report

if not os.path.exists(CHROMIUM):
    if os.environ.get("CI"):
        pytest.fail(f"{CHROMIUM} is missing: .ci/run installs Debian's chromium", pytrace=False)
    pytest.skip(f"no {CHROMIUM} (apt-get install chromium)", allow_module_level=True)
sync_api = pytest.importorskip("playwright.sync_api")


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as pw:
        b = launch(pw)
        yield b
        b.close()


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = rs.write_and_run(tmp_path_factory.mktemp("browser"))
    assert main(["sensitivity", str(folder), "--metric", "peak_deceleration_g.body"]) == 0
    out = folder.parent / "report.html"
    assert main(["report", str(folder), "-o", str(out)]) == 0
    return out


def test_report_renders_in_chromium(browser, report: Path, tmp_path: Path) -> None:
    page, seen = open_report(browser, report)
    try:
        page.screenshot(path=str(tmp_path / "report.png"), full_page=True)
        assert seen["errors"] == []
        assert seen["requests"] == []  # nothing fetched: every script and style is in the file
        # nothing in the page points outside it
        external = page.eval_on_selector_all(
            "[src],[href]",
            "es => es.map(e => e.getAttribute('src') || e.getAttribute('href'))"
            ".filter(u => !u.startsWith('#') && !u.startsWith('data:') && !u.startsWith('blob:'))",
        )
        assert external == []
        # every figure drawn, with a nonzero size; parallel coordinates, anthill, criteria, history, sensitivity
        sizes = page.eval_on_selector_all(
            "div.fig",
            "ds => ds.map(d => { const s = d.querySelector('.main-svg');"
            " const r = s.getBoundingClientRect(); return [r.width, r.height]; })",
        )
        assert len(sizes) >= 8 and all(w > 100 and h > 100 for w, h in sizes)
        assert page.locator("div.fig .parcoords").count() == 1
        assert page.locator("div.fig .scatterlayer .point").count() > 0
        # the table: one row per variant once every row is shown; sorting and filtering work in the page
        page.select_option("#cs-pagesize", "all")
        assert page.locator("#cs-table tbody tr").count() == len(rs.MASSES) * len(rs.SPEEDS)
        page.fill("#cs-filter", "status=failed")
        failed = page.locator("#cs-table tbody tr td:first-child").all_inner_texts()
        assert failed == ["2", "5"]
        page.fill("#cs-filter", "peak_deceleration_g.body>11")
        assert page.locator("#cs-table tbody tr").count() == 2  # the two ok 800 kg variants: 12.75 g
        page.fill("#cs-filter", "")
        page.click("#cs-table th:nth-child(1)")
        page.click("#cs-table th:nth-child(1)")  # variant, descending
        assert page.locator("#cs-table tbody tr td:first-child").first.inner_text() == "5"
        # the failures section names the failed variants with their reasons
        rows = page.locator("#failures table tbody tr").all_inner_texts()
        assert [r.split("\t")[0] for r in rows] == ["2", "5"] and all("critical step" in r for r in rows)
        page.screenshot(path=str(tmp_path / "table.png"))
        assert (tmp_path / "report.png").stat().st_size > 10_000
    finally:
        page.close()
