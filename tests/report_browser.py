"""Headless Chromium for the report tests and the README screenshot (benchmarks/report_screenshot.py).

Debian's ``chromium`` (``/usr/bin/chromium``, installed by ``.ci/run``) driven by Python playwright with
``executable_path``: playwright never downloads a browser of its own. Software WebGL (SwiftShader) draws
the parallel-coordinates figure without a GPU.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

TIMEOUT_MS = (
    300_000  # a loaded 2-core CI machine parses 4.5 MiB of script and draws 10 figures slowly (30 s seen)
)
CHROMIUM = os.environ.get("CRASHSTUDY_CHROMIUM", "/usr/bin/chromium")
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    "--enable-unsafe-swiftshader",
]


def launch(pw: Any) -> Any:
    return pw.chromium.launch(executable_path=CHROMIUM, args=FLAGS, headless=True)


def open_report(
    browser: Any, path: Path, width: int = 1280, height: int = 900
) -> tuple[Any, dict[str, list]]:
    """A page showing the report at ``path``, every network request other than the file itself refused
    and recorded; returns (page, {"errors": console errors and page errors, "requests": refused URLs})."""
    seen: dict[str, list] = {"errors": [], "requests": []}
    page = browser.new_page(viewport={"width": width, "height": height})
    page.set_default_timeout(TIMEOUT_MS)
    url = path.resolve().as_uri()

    def route(r: Any) -> None:
        if r.request.url == url:
            r.continue_()
        else:
            seen["requests"].append(r.request.url)
            r.abort()

    page.route("**/*", route)
    page.on("console", lambda m: seen["errors"].append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: seen["errors"].append(str(e)))
    page.goto(url, wait_until="load", timeout=TIMEOUT_MS)
    page.wait_for_function(
        "Array.from(document.querySelectorAll('div.fig')).every(d => d.querySelector('.main-svg'))",
        timeout=TIMEOUT_MS,
    )
    return page, seen
