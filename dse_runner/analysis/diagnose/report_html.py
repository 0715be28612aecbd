"""A diagnosis report as one HTML file: the Markdown report rendered, its figures inlined.

Why: the Markdown report and its PNG figures are a folder; a colleague is sent one file. Like ``report``'s
sweep report, ``diagnosis.html`` holds everything (figures as data URIs, the style in the page), so it
opens offline and from an e-mail. Every library writes its Markdown report and gets this page from it.
"""

from __future__ import annotations

import base64
import html
import mimetypes
from pathlib import Path

from markdown_it import MarkdownIt

PAGE = "diagnosis.html"
STYLE = """
body { font-family: system-ui, sans-serif; max-width: 60rem; margin: 2rem auto; padding: 0 1rem;
       line-height: 1.45; color: #222; }
table { border-collapse: collapse; margin: 1rem 0; font-size: 0.9rem; display: block; overflow-x: auto; }
th, td { border: 1px solid #ccc; padding: 0.25rem 0.5rem; text-align: left; }
th { background: #f3f3f3; }
img { max-width: 100%; height: auto; }
code { background: #f6f6f6; padding: 0 0.2rem; }
pre { background: #f6f6f6; padding: 0.5rem; overflow-x: auto; }
"""


def inlined(source: str, folder: Path) -> str:
    """An image's address as a data URI of the file it names inside ``folder``; the address as it was when
    it names no such file (a web address, or a figure that was not drawn)."""
    path = folder / source
    if "://" in source or source.startswith("data:") or not path.is_file():
        return source
    kind = mimetypes.guess_type(path.name)[0] or "application/octet-stream"
    return f"data:{kind};base64,{base64.b64encode(path.read_bytes()).decode('ascii')}"


def page(markdown: str, folder: Path, title: str) -> str:
    """The report's Markdown as a whole HTML page, its images (relative to ``folder``) inlined."""
    parser = MarkdownIt("commonmark", {"html": False}).enable("table")
    tokens = parser.parse(markdown)
    for token in tokens:
        for child in token.children or []:
            if child.type == "image":
                child.attrSet("src", inlined(str(child.attrGet("src")), folder))
    body = parser.renderer.render(tokens, parser.options, {})
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{html.escape(title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n{body}</body>\n</html>\n"
    )


def write(report: Path, title: str) -> Path:
    """``diagnosis.html`` beside the Markdown ``report``, from it; its path."""
    target = report.with_name(PAGE)
    target.write_text(page(report.read_text(), report.parent, title))
    return target
