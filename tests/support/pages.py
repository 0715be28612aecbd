"""What a browser shows of a page's Bokeh charts, measured in the page: whether every chart fits the page's
width, whether every title fits its chart (Bokeh draws titles on the canvas, which cuts off what runs past
its edge) and clears the chart's toolbar, and which glyphs a named chart draws."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

# Walks BokehJS's views (Bokeh.index), not the DOM: the charts live in shadow roots, and a title is canvas
# pixels, so its extent is the text box BokehJS measured to draw it, placed where the title's view sits.
MEASURE = """() => {
  const views = [];
  const walk = (view) => { views.push(view); for (const child of view.child_views || []) walk(child); };
  for (const root of Bokeh.index.roots) walk(root);
  const body = document.body.getBoundingClientRect();
  const page = Math.min(document.documentElement.clientWidth, body.right);
  const charts = [];
  for (const view of views) {
    if (!view.renderer_views || !view.canvas_view || !('title' in view.model.properties)) continue;
    const box = view.el.getBoundingClientRect();
    const canvas = view.canvas_view.el.getBoundingClientRect();
    const chart = {name: view.model.name || '', right: box.right, page: page, title: '', title_right: 0,
                   canvas_right: canvas.right, toolbar_left: null};
    const title = view.model.title && view.renderer_views.get(view.model.title);
    if (title && title.model.text) {
      const size = title._text_box.size();
      chart.title = title.model.text;
      chart.title_right = canvas.left + title.bbox.x0 + size.width;
      const top = canvas.top + title.bbox.y0, bottom = top + size.height;
      const toolbar = view.model.toolbar && view.owner.find_one(view.model.toolbar);
      const bar = toolbar && toolbar.el.getBoundingClientRect();
      if (bar && bar.width > 0 && bar.top < bottom && bar.bottom > top) chart.toolbar_left = bar.left;
    }
    charts.push(chart);
  }
  return {charts: charts, scroll_width: document.documentElement.scrollWidth,
          client_width: document.documentElement.clientWidth};
}"""

GLYPHS = """(name) => { for (const doc of Bokeh.documents) { const chart = doc.get_model_by_name(name);
  if (chart) return chart.renderers.map(r => [r.glyph.type, r.data_source.get_length()]); } return null }"""


@dataclass
class Fit:
    """What :func:`measure` found: how many charts and titles, and what does not fit, in words."""

    charts: int
    titles: int
    misfits: list[str]


def measure(page) -> Fit:
    """Every Bokeh chart on ``page``: its right edge within the page (the body's box and the window), its
    title within its canvas and left of a toolbar on its line; and the page not scrolling sideways."""
    found = page.evaluate(MEASURE)
    misfits = []
    for chart in found["charts"]:
        name = chart["title"] or chart["name"] or "a chart"
        if chart["right"] > chart["page"] + 0.5:
            misfits.append(
                f"{name}: right edge at {chart['right']:.0f} px, past the page's {chart['page']:.0f}"
            )
        if chart["title"] and chart["title_right"] > chart["canvas_right"] + 0.5:
            misfits.append(
                f"title {name!r} ends at {chart['title_right']:.0f} px, past its canvas "
                f"({chart['canvas_right']:.0f})"
            )
        if chart["toolbar_left"] is not None and chart["title_right"] > chart["toolbar_left"] + 0.5:
            misfits.append(
                f"title {name!r} runs under its toolbar ({chart['title_right']:.0f} > "
                f"{chart['toolbar_left']:.0f} px)"
            )
    if found["scroll_width"] > found["client_width"]:
        misfits.append(
            f"the page scrolls sideways: {found['scroll_width']} px wide in a "
            f"{found['client_width']} px window"
        )
    return Fit(len(found["charts"]), sum(bool(c["title"]) for c in found["charts"]), misfits)


def glyphs(page, name: str) -> list[tuple[str, int]] | None:
    """The glyphs the chart named ``name`` draws, each with its data source's rows (those with any: a chart
    keeps empty glyphs for what another design would draw); None if no such chart."""
    drawn = page.evaluate(GLYPHS, name)
    return None if drawn is None else [(kind, rows) for kind, rows in drawn if rows]


def chromium(playwright):
    """Debian's Chromium: what .ci/install puts on the machine (apt-get install chromium)."""
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    assert path, "no chromium on PATH: install Debian's (apt-get install chromium), as .ci/install does"
    return playwright.chromium.launch(executable_path=path)


def watch_errors(page, errors: list[str]) -> None:
    """Append the page's console errors and uncaught exceptions to ``errors``."""
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))


@contextmanager
def browser_page(errors: list[str] | None = None, **context: Any) -> Iterator[Any]:
    """A page in a Chromium of its own, closed with it on leaving; ``context`` goes to the browser context
    (``viewport={...}``, ``offline=True``), and with ``errors`` the page's errors are collected there.
    Playwright's sync API is opened here and closed again: kept open, it marks the thread's event loop as
    running, and ``asyncio.run`` elsewhere in the test process would fail."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = chromium(playwright)
        try:
            page = browser.new_context(**context).new_page()
            if errors is not None:
                watch_errors(page, errors)
            yield page
        finally:
            browser.close()


def open_dashboard(page, url: str, timeout: float = 30_000) -> None:
    """Go to a dashboard page and wait until BokehJS has drawn its document: the counts the page's HTML shows
    first (#dse-first) are gone then, and every live part is the document's."""
    page.goto(url)
    page.wait_for_selector("#dse-first", state="detached", timeout=timeout)
    page.wait_for_selector("#dse-done", timeout=timeout)
