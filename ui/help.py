"""The algorithms' help, read from their docs pages (docs/algorithms/<id>.md, shipped in the plugin zip):
the dialog's short help is the page's summary (the text between its title and its first section),
rendered to the simple HTML the Processing dialog shows, with a link to the page."""
from __future__ import annotations

import html
import re
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"
ALGORITHM_PAGES = DOCS / "algorithms"

_LINK = re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)")
_BOLD = re.compile(r"\*\*(.+?)\*\*")
_CODE = re.compile(r"`([^`]+)`")
_ITALIC = re.compile(r"(?<![*\w])\*([^*\s][^*]*?)\*(?![*\w])")


def help_page(algorithm_id: str) -> Path:
    """The docs page of algorithm ``algorithm_id`` (the id without the provider's prefix)."""
    return ALGORITHM_PAGES / f"{algorithm_id}.md"


def summary_markdown(page: Path) -> str:
    """The page's summary: its lines after the title (``# ...``) up to its first ``## `` section."""
    lines = page.read_text(encoding="utf-8").splitlines()
    body = lines[1:] if lines and lines[0].startswith("# ") else lines
    end = next((i for i, line in enumerate(body) if line.startswith("## ")), len(body))
    return "\n".join(body[:end]).strip()


def inline_html(text: str, folder: Path) -> str:
    """One paragraph's Markdown (bold, italic, code, links) as HTML; a relative link becomes a file URL
    under ``folder`` (the page's folder)."""
    out = html.escape(text, quote=False)
    out = _BOLD.sub(r"<b>\1</b>", out)
    out = _CODE.sub(r"<code>\1</code>", out)
    out = _ITALIC.sub(r"<i>\1</i>", out)

    def link(match: re.Match) -> str:
        target = match.group(2)
        if not re.match(r"[a-z]+:", target):
            page, _, anchor = target.partition("#")
            target = (folder / page).resolve().as_uri() + (f"#{anchor}" if anchor else "")
        return f'<a href="{target}">{match.group(1)}</a>'

    return _LINK.sub(link, out)


def markdown_html(text: str, folder: Path) -> str:
    """Paragraphs and '- ' lists of simple Markdown as HTML (<p>, <ul><li>)."""
    blocks = []
    for block in re.split(r"\n\s*\n", text.strip()):
        lines = block.splitlines()
        if lines and all(line.startswith(("- ", "  ")) for line in lines):
            items = re.split(r"\n- ", "\n" + block.strip())[1:]
            blocks.append("<ul>" + "".join(f"<li>{inline_html(' '.join(i.split()), folder)}</li>"
                                             for i in items) + "</ul>")
        else:
            blocks.append(f"<p>{inline_html(' '.join(block.split()), folder)}</p>")
    return "".join(blocks)


def short_help(algorithm_id: str, translate=str) -> str:
    """The dialog's help of ``algorithm_id``: the summary of its docs page (through ``translate``, the
    plugin's tr) as HTML, then a link to the page; '' without a page."""
    page = help_page(algorithm_id)
    if not page.is_file():
        return ""
    link = f'<p><a href="{page.as_uri()}">{translate("Full documentation")}</a>: docs/algorithms/{page.name}</p>'
    return markdown_html(translate(summary_markdown(page)), page.parent) + link
