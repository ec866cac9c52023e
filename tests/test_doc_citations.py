"""Docstrings cite a page's section by its title, not by a number that drifts when a section is added
(issue #30): every ``docs/<page>.md, "Title"`` in the code names a heading that exists on that page, and no
``<page>.md §N`` is left. (Section numbers of the papers, "2020 paper §3.4", are the papers' own and stay.)"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = r"(\w+)\.md(?:``|`)?"
TITLE = r'"([^"\n]+)"'  # a title in double quotes; inside a double-quoted message the code writes 'Title'
TITLE1 = r"'([^'\n]+?)'(?!s\b)"
CITE = re.compile(PAGE + r",\s*(?:" + TITLE + "|" + TITLE1 + r")((?:(?:,|\s+and|\s+to)\s*(?:" + TITLE + "|" + TITLE1
                  + r"))*)")


def _page(page: str) -> Path:
    """docs/<page>.md, or a page at the repository's root (CONTRIBUTING.md)."""
    return ROOT / "docs" / f"{page}.md" if (ROOT / "docs" / f"{page}.md").is_file() else ROOT / f"{page}.md"


def _headings(page: str) -> set[str]:
    """A page's section titles (numbers and backquotes taken off) and its paragraphs' bold labels
    (``- **Stopping.** ...``)."""
    text = _page(page).read_text()
    heads = {re.sub(r"^\d+(?:\.\d+)*\.?\s+", "", m) for m in re.findall(r"^#{1,4} (.+?)\s*$", text, re.M)}
    heads |= {m.rstrip(".") for m in re.findall(r"\*\*([^*\n]+?)\*\*", text)}
    return {h.replace("`", "") for h in heads}


def _flat(source: str) -> str:
    """The source with string joins (``"...abc "`` then ``"def"`` on the next line), line breaks, indentation
    and comment marks taken out, so that a title wrapped over two lines reads as one."""
    source = re.sub(r'"\s*\n\s*"', "", source)
    return re.sub(r"\s*\n\s*(?:#\s*)?", " ", source)


def citations():
    for path in sorted((ROOT / "optcal").rglob("*.py")):
        flat = _flat(path.read_text())
        for m in CITE.finditer(flat):
            page, first, rest = m.group(1), m.group(2) or m.group(3), m.group(4)
            titles = [first] + [a or b for a, b in re.findall(TITLE + "|" + TITLE1, rest or "")]
            for title in titles:
                yield path.relative_to(ROOT), page, " ".join(title.replace("`", "").split())


def test_every_cited_section_exists():
    found = list(citations())
    assert len(found) > 200  # the scan sees the citations
    heads: dict[str, set[str]] = {}
    missing = []
    for path, page, title in found:
        if not _page(page).is_file():
            missing.append(f"{path}: {page}.md does not exist")
            continue
        known = heads.setdefault(page, _headings(page))
        if title not in known and not any(h.startswith(title) for h in known):
            missing.append(f"{path}: docs/{page}.md has no section {title!r}")
    assert missing == []


def test_no_section_number_of_our_pages_is_cited():
    numbered = [f"{p.relative_to(ROOT)}: {m}" for p in sorted((ROOT / "optcal").rglob("*.py"))
                for m in re.findall(r"\w+\.md(?:``|`)?,?\s+§\d[\d.]*", _flat(p.read_text()))]
    assert numbered == []


def test_the_check_can_fail():
    assert list(CITE.finditer('(docs/design.md, "No such section" and "Units and frames")'))
    flat = _flat('docs/design.md, "Terms and\n    parameters"')
    assert [m.group(2) for m in CITE.finditer(flat)] == ["Terms and parameters"]
    assert [m.group(3) for m in CITE.finditer("(docs/design.md, 'Raw recordings')")] == ["Raw recordings"]
    assert "No such section" not in _headings("design")
