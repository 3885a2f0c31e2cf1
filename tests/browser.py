"""Open an HTML report in a real headless browser (Debian's chromium, driven by Playwright)
and record what a reader's browser would do: console messages, every request, the text,
and the pixels of the 3D view's WebGL canvas."""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

CHROMIUM_CANDIDATES = ("/usr/bin/chromium", "/usr/bin/chromium-browser")
# WebGL without a GPU (SwiftShader), and no attempt to reach Google's hosts.
CHROMIUM_ARGS = [
    "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
    "--disable-background-networking", "--disable-component-update", "--no-first-run",
    "--disable-default-apps", "--disable-sync", "--metrics-recording-only",
]


def chromium_path() -> str:
    """The browser to drive; missing, the test fails in CI (CI=true) and skips elsewhere."""
    for candidate in (os.environ.get("SCENE3D_CHROMIUM"), *CHROMIUM_CANDIDATES,
                      shutil.which("chromium")):
        if candidate and Path(candidate).is_file():
            return candidate
    message = "no chromium browser found (apt-get install chromium; .ci/run installs it)"
    if os.environ.get("CI"):
        pytest.fail(message)
    pytest.skip(message)


@dataclass
class PageVisit:
    """What happened while the page was open."""

    console: list[tuple[str, str]] = field(default_factory=list)  # (type, text)
    page_errors: list[str] = field(default_factory=list)
    requests: list[str] = field(default_factory=list)
    text: str = ""
    canvas_pixels: np.ndarray | None = None  # (H, W, 3): the 3D view as it opened
    canvas_after_drag: np.ndarray | None = None  # after a mouse drag over it
    canvas_without_clouds: np.ndarray | None = None  # same camera, point clouds hidden
    relayout_keys: list[str] = field(default_factory=list)  # plotly events of the drag
    images: int = 0  # <img> elements
    broken_images: int = 0  # <img> elements that did not decode
    screenshot: bytes = b""

    @property
    def errors(self) -> list[str]:
        return [t for kind, t in self.console if kind == "error"] + self.page_errors

    @property
    def outside_requests(self) -> list[str]:
        """Requests for anything but the file itself and ``data:`` / ``blob:`` URLs."""
        return [u for u in self.requests if not u.startswith(("file:", "data:", "blob:"))]


def visit(path: Path, wait_for_view: bool, screenshot_path: Path | None = None) -> PageVisit:
    """Open ``path`` (file: URL) in headless chromium and record the visit."""
    from playwright.sync_api import sync_playwright

    result = PageVisit()
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium_path(), headless=True,
                                    args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            # A dense view (300,000 points) takes SwiftShader some 40 s on two busy cores.
            page.set_default_timeout(120_000)
            page.on("console", lambda m: result.console.append((m.type, m.text)))
            page.on("pageerror", lambda e: result.page_errors.append(str(e)))
            page.on("request", lambda r: result.requests.append(r.url))
            page.goto(path.resolve().as_uri(), wait_until="load", timeout=120_000)
            result.text = page.inner_text("body")
            result.images, result.broken_images = page.evaluate(
                "() => { const im = [...document.images]; return [im.length,"
                " im.filter(i => !i.complete || i.naturalWidth === 0).length]; }")
            if wait_for_view:
                _inspect_view(page, result)
            result.screenshot = page.screenshot(full_page=False)
            if screenshot_path is not None:
                screenshot_path.write_bytes(result.screenshot)
        finally:
            browser.close()
    return result


def _shot(locator) -> np.ndarray:
    import cv2

    png = locator.screenshot(timeout=120_000)  # SwiftShader on a loaded machine
    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)


def _inspect_view(page, result: PageVisit) -> None:
    """Screenshots of the 3D view with and without the point clouds, and a drag."""
    # plotly draws the scene into a WebGL canvas inside #view3d.
    page.wait_for_selector("#view3d .gl-container canvas", timeout=120_000)
    view = page.locator("#view3d")
    view.scroll_into_view_if_needed()
    page.evaluate("() => Plotly.relayout('view3d', {showlegend: false})")
    page.wait_for_timeout(1000)
    result.canvas_pixels = _shot(view)
    page.evaluate("""() => {
        const gd = document.getElementById('view3d');
        window.__relayouts = [];
        gd.on('plotly_relayout', e => window.__relayouts.push(...Object.keys(e)));
    }""")
    box = view.bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 120, y + 40, steps=8)
    page.mouse.up()
    page.wait_for_timeout(500)
    result.relayout_keys = page.evaluate("() => window.__relayouts")
    _show_clouds(page, False)
    page.wait_for_timeout(1000)
    # After the drag the camera has moved: compare with the clouds hidden, same camera.
    _show_clouds(page, True)
    page.wait_for_timeout(1000)
    result.canvas_after_drag = _shot(view)
    _show_clouds(page, False)
    page.wait_for_timeout(1000)
    result.canvas_without_clouds = _shot(view)


def changed_fraction(a: np.ndarray, b: np.ndarray, threshold: int = 40) -> float:
    """Fraction of pixels whose colour differs by more than ``threshold`` in some channel."""
    diff = np.abs(a.astype(np.int16) - b.astype(np.int16)).max(axis=2)
    return float(np.mean(diff > threshold))


def _show_clouds(page, visible: bool) -> None:
    """Show or hide every trace of the 3D view but the cameras."""
    page.evaluate("""visible => {
        const gd = document.getElementById('view3d');
        const clouds = gd.data.map((t, i) => i).filter(i => !gd.data[i].name.startsWith('camera'));
        return Plotly.restyle(gd, {visible: visible}, clouds);
    }""", visible)
