"""The algorithms' help, read from the docs (shipped in the plugin zip): the dialog's short help from the
summary of docs/algorithms/<id>.md, each parameter's help from its entry in the page's section Parameters
or in docs/parameters.md (the format: that page's introduction)."""
from __future__ import annotations

import html
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

DOCS = Path(__file__).resolve().parents[1] / "docs"
ALGORITHM_PAGES = DOCS / "algorithms"
VOCABULARY_PAGE = DOCS / "parameters.md"
SECTION = "## Parameters"

_LINK = re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)")
_BOLD = re.compile(r"\*\*(.+?)\*\*")
_CODE = re.compile(r"`([^`]+)`")
_ITALIC = re.compile(r"(?<![*\w])\*([^*\s][^*]*?)\*(?![*\w])")
_NAME = r"[A-Z][A-Z0-9_]*"
_ENTRY = re.compile(rf"- \*\*(?P<label>.+?)\*\* \((?:`(?P<name>{_NAME})`"
                    rf"|\[`(?P<shared>{_NAME})`\]\([^)\s]*parameters\.md[^)\s]*\))\)(?::\s*(?P<text>.*))?$", re.S)
_VALUE = re.compile(r"- `(?P<value>[a-z][a-z0-9_]*)`: (?P<meaning>.+)$", re.S)


@dataclass(frozen=True)
class Entry:
    """A parameter's (or output's) entry in a ``## Parameters`` section: its Markdown ``text`` and, for
    an enumeration, its ``values`` (name, meaning) in order; ``shared`` when its name links to
    docs/parameters.md (the entry there comes first)."""
    name: str
    label: str
    text: str
    values: tuple[tuple[str, str], ...] = ()
    shared: bool = False


def help_page(algorithm_id: str) -> Path:
    """The docs page of algorithm ``algorithm_id`` (the id without the provider's prefix)."""
    return ALGORITHM_PAGES / f"{algorithm_id}.md"


def summary_markdown(page: Path) -> str:
    """The page's summary: its lines after the title (``# ...``) up to its first ``## `` section."""
    lines = page.read_text(encoding="utf-8").splitlines()
    body = lines[1:] if lines and lines[0].startswith("# ") else lines
    end = next((i for i, line in enumerate(body) if line.startswith("## ")), len(body))
    return "\n".join(body[:end]).strip()


def section_items(lines: list[str], whole: bool = False) -> list[list[str]]:
    """The list items of a page's lines (an item: its '- ' line and the lines indented under it), from
    ``## Parameters`` up to the next section (of the whole page with ``whole``)."""
    if not whole:
        start = next((i + 1 for i, line in enumerate(lines) if line.strip() == SECTION), len(lines))
        end = next((i for i in range(start, len(lines)) if lines[i].startswith("## ")), len(lines))
        lines = lines[start:end]
    items = []
    for line in lines:
        if line.startswith("- "):
            items.append([line])
        elif line.startswith("  ") and items and line.strip():
            items[-1].append(line)
        elif line.strip() and items and items[-1]:
            items.append([])  # a paragraph ends the item before it
    return [item for item in items if item]


def entry_of(item: list[str], where: Path) -> Entry:
    """One item as an :class:`Entry`; ValueError naming the page and line when it is not one."""
    values, main = [], []
    for line in item:
        if line.startswith("  - "):
            values.append(line[2:])
        elif values and line.startswith("    "):
            values[-1] += "\n" + line
        else:
            main.append(line)
    match = _ENTRY.match("\n".join(main))
    value_matches = [_VALUE.match(v) for v in values]
    if match is None or not all(value_matches):
        raise ValueError(f"{where}: not a parameter entry ('- **Label** (`NAME`): text'): {item[0]!r}")
    return Entry(match["name"] or match["shared"], match["label"], " ".join((match["text"] or "").split()),
                 tuple((m["value"], " ".join(m["meaning"].split())) for m in value_matches), bool(match["shared"]))


@lru_cache(maxsize=None)
def page_entries(page: Path) -> tuple[Entry, ...]:
    """The entries of the ``## Parameters`` section of ``page`` (of the whole of docs/parameters.md),
    in order; () for a missing page."""
    if not page.is_file():
        return ()
    lines = page.read_text(encoding="utf-8").splitlines()
    return tuple(entry_of(item, page) for item in section_items(lines, whole=page == VOCABULARY_PAGE))


@lru_cache(maxsize=None)
def vocabulary() -> dict[str, Entry]:
    """docs/parameters.md: the shared parameters by name (one dict, not to be changed)."""
    return {entry.name: entry for entry in page_entries(VOCABULARY_PAGE)}


def resolved(entry: Entry) -> Entry:
    """``entry`` with the shared text first (and the shared values, unless it lists its own) when its
    name links to docs/parameters.md."""
    if not entry.shared:
        return entry
    shared = vocabulary().get(entry.name)
    if shared is None:
        raise ValueError(f"{VOCABULARY_PAGE}: no entry for {entry.name}, which an algorithm's page links to")
    return Entry(entry.name, entry.label, " ".join(filter(None, (shared.text, entry.text))),
                 entry.values or shared.values, True)


def plain_text(markdown: str) -> str:
    """Inline Markdown as plain text: links become their text, emphasis and code marks are dropped
    (a code span is kept as written), backslash escapes are undone."""
    parts = _CODE.split(_LINK.sub(r"\1", " ".join(markdown.split())))
    for k in range(0, len(parts), 2):
        parts[k] = re.sub(r"\\([\\`*_<>\[\]#])", r"\1", _ITALIC.sub(r"\1", _BOLD.sub(r"\1", parts[k])))
    return "".join(parts)


def help_text(entry: Entry, translate=str) -> str:
    """The help QGIS shows for an entry: its text, then an enumeration's values by name with what
    each means, as plain text through ``translate`` (the plugin's tr)."""
    text = translate(plain_text(entry.text))
    if not entry.values:
        return text
    example = f"{entry.name}={entry.values[0][0]}"
    values = "; ".join(f"{value}: {translate(plain_text(meaning))}" for value, meaning in entry.values)
    intro = translate("Values, by name (e.g. {example}; option numbers are refused)").format(example=example)
    return f"{text} {intro}: {values}."


def parameter_help(algorithm_id: str, translate=str) -> dict[str, str]:
    """{NAME: help text} of every parameter and output the page of ``algorithm_id`` documents."""
    return {e.name: help_text(resolved(e), translate) for e in page_entries(help_page(algorithm_id))}


def documented_help(algorithm_id: str, name: str, translate=str) -> str:
    """The help of parameter ``name`` from the page of ``algorithm_id`` ('' when it has no entry there)."""
    entry = next((e for e in page_entries(help_page(algorithm_id)) if e.name == name), None)
    return help_text(resolved(entry), translate) if entry else ""


def shared_help(name: str, translate=str) -> str:
    """The help of parameter ``name`` in docs/parameters.md ('' when it has no entry there)."""
    entry = vocabulary().get(name)
    return help_text(entry, translate) if entry else ""


def inline_html(text: str, page: Path) -> str:
    """One paragraph's Markdown (bold, italic, code, links) of ``page`` as HTML; a relative link becomes
    a file URL (an anchor alone: in ``page``)."""
    out = html.escape(text, quote=False)
    out = _BOLD.sub(r"<b>\1</b>", out)
    out = _CODE.sub(r"<code>\1</code>", out)
    out = _ITALIC.sub(r"<i>\1</i>", out)

    def link(match: re.Match) -> str:
        target = match.group(2)
        if not re.match(r"[a-z]+:", target):
            path, _, anchor = target.partition("#")
            target = (page.parent / path if path else page).resolve().as_uri() + (f"#{anchor}" if anchor else "")
        return f'<a href="{target}">{match.group(1)}</a>'

    return _LINK.sub(link, out)


def markdown_html(text: str, page: Path) -> str:
    """Paragraphs and '- ' lists of simple Markdown as HTML (<p>, <ul><li>)."""
    blocks = []
    for block in re.split(r"\n\s*\n", text.strip()):
        lines = block.splitlines()
        if lines and all(line.startswith(("- ", "  ")) for line in lines):
            items = re.split(r"\n- ", "\n" + block.strip())[1:]
            blocks.append("<ul>" + "".join(f"<li>{inline_html(' '.join(i.split()), page)}</li>"
                                             for i in items) + "</ul>")
        else:
            blocks.append(f"<p>{inline_html(' '.join(block.split()), page)}</p>")
    return "".join(blocks)


def named_list(parameters: list[tuple[str, str]]) -> str:
    """'<b>Label</b> (<code>NAME</code>), ...' of (label, name) pairs."""
    return ", ".join(f"<b>{html.escape(label)}</b> (<code>{name}</code>)" for label, name in parameters)


def short_help(algorithm_id: str, translate=str, shown=(), hidden: int = 0, outputs=()) -> str:
    """The dialog's help of ``algorithm_id``: the summary of its docs page (through ``translate``, the
    plugin's tr) as HTML, the inputs the dialog shows and the outputs ((label, name) pairs; ``hidden``:
    how many inputs are under 'Advanced parameters'), then a link to the page; '' without a page."""
    page = help_page(algorithm_id)
    if not page.is_file():
        return ""
    inputs = f"<b>{translate('Inputs')}:</b> {named_list(shown)}"
    if hidden:
        inputs += "; " + translate("{n} more under <i>Advanced parameters</i>").format(n=hidden)
    listed = f"<p>{inputs}.</p>" + (f"<p><b>{translate('Outputs')}:</b> {named_list(outputs)}.</p>" if outputs else "")
    link = (f'<p><a href="{page.as_uri()}">{translate("Full documentation")}</a>: docs/algorithms/{page.name} '
            f'({translate("every parameter in its section Parameters")})</p>')
    return markdown_html(translate(summary_markdown(page)), page) + listed + link
