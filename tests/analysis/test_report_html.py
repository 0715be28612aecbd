"""diagnosis.html: the diagnosis report as one page that opens offline, its figures inside it, checked in a
real browser (Debian's Chromium, as the sweep report is)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from support.pages import browser_page

from dse_runner.analysis.diagnose import report_html

REPORT = """# Diagnosis of msd

**Verdict** explained: `input_delay(msd.F)` leaves 1.1 noise floors.

| effect | parameter | value |
|---|---|---|
| input_delay(msd.F) | delay | 0.3 |

![residuals](figures/residuals.png)

![never drawn](figures/missing.png)
"""


def test_the_report_is_one_page_whose_figures_show_offline(tmp_path):
    (tmp_path / "figures").mkdir()
    fig, ax = plt.subplots(figsize=(4, 3))
    ax.plot([0, 1, 2], [0, 1, 0])
    fig.savefig(tmp_path / "figures" / "residuals.png")
    plt.close(fig)
    report = tmp_path / "diagnosis-report.md"
    report.write_text(REPORT)

    page = report_html.write(report, "Diagnosis of msd <1>")
    text = page.read_text()
    assert page.name == "diagnosis.html" and "data:image/png;base64," in text
    assert "<title>Diagnosis of msd &lt;1&gt;</title>" in text
    assert 'src="figures/missing.png"' in text  # a figure that is not there stays a link, not an error

    (tmp_path / "figures" / "residuals.png").unlink()  # the page must not need the folder any more
    errors: list[str] = []
    with browser_page(errors, offline=True) as browser:
        browser.goto(page.as_uri())
        shown = browser.evaluate(
            "() => [...document.images].map(i => [i.alt, i.complete && i.naturalWidth > 0])"
        )
        cells = browser.evaluate("() => [...document.querySelectorAll('td')].map(c => c.textContent)")
    assert dict(shown) == {"residuals": True, "never drawn": False}
    assert cells == ["input_delay(msd.F)", "delay", "0.3"]
