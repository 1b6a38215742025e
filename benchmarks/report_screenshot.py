"""The README's screenshot of ``crashstudy report``: the page opened in the same headless Chromium as the
browser test (tests/report_browser.py), checked the same way (no console error, no request), and the top of
its study and design-space sections captured.

Run: ``python benchmarks/report_screenshot.py results/frontal-occupant-matrix/report.html docs/img/report.png``.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from report_browser import launch, open_report  # noqa: E402


def main() -> None:
    from playwright.sync_api import sync_playwright

    html, png = Path(sys.argv[1]), Path(sys.argv[2])
    with sync_playwright() as pw:
        browser = launch(pw)
        page, seen = open_report(browser, html, width=1100, height=760)
        assert not seen["errors"] and not seen["requests"], seen
        top = page.evaluate("document.getElementById('design').getBoundingClientRect().top + window.scrollY")
        page.screenshot(
            path=str(png), full_page=True, clip={"x": 0, "y": top - 8, "width": 1100, "height": 760}
        )
        browser.close()
    print(f"wrote {png}")


if __name__ == "__main__":
    main()
