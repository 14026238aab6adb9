"""Invariants of the documentation's cross-references: every docs page that the code, the tests, the
README or another page names exists, and every section it names there ("Short logs", section 2), or
that a page names in itself ("Short logs" above), is in that page. The pages are split and renamed as
they grow; a message that sends a user to a section that moved is a defect no other test sees."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _sources() -> list[Path]:
    files = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]
    for folder in ("src", "tests", "benchmarks"):
        files += sorted((ROOT / folder).rglob("*.py"))
    return files


# a page named as docs/<page>.md or as a Markdown link, then optionally `, "Section"`, `, Known limits)`
# (a capitalized name of two to four words) or `, section N`
_REF = re.compile(
    r"(?:docs/(?P<page>[a-z0-9-]+\.md)|\[[^\]\n]*\]\((?P<linked>[a-z0-9-]+\.md)\))`?(?:'s)?"
    r"(?:,?\s+(?:section\s+(?P<num>\d)\b|\"(?P<name>[^\"]{3,120})\"|(?P<bare>[A-Z][a-z]+(?: [a-z]+){1,3})(?=[).])))?"
)


def _references() -> list[tuple[str, str, str | None, str | None]]:
    refs = []
    for path in _sources():
        for m in _REF.finditer(path.read_text(encoding="utf-8")):
            refs.append((str(path.relative_to(ROOT)), m["page"] or m["linked"], m["num"], m["name"] or m["bare"]))
    return refs


REFERENCES = _references()


def test_the_references_are_found():
    # the scan itself must see the references it guards (a regex that matches nothing would pass)
    pages = {page for _, page, _, _ in REFERENCES}
    assert {"em-real.md", "cli-reference.md", "formats.md", "em.md"} <= pages
    assert any(name == "Short logs" for _, page, _, name in REFERENCES if page == "em-real.md")
    assert any(num == "2" for _, page, num, _ in REFERENCES if page == "em-real.md")


@pytest.mark.parametrize("where,page,num,name", REFERENCES, ids=[f"{w}->{p}" for w, p, _, _ in REFERENCES])
def test_a_named_page_and_section_exist(where, page, num, name):
    target = DOCS / page
    assert target.is_file(), f"{where} names docs/{page}, which does not exist"
    text = target.read_text(encoding="utf-8")
    if num is not None:
        assert re.search(rf"^## {num}\. ", text, re.M), f"{where} names section {num} of {page}, which has none"
    if name is not None:
        # the name must head something (a heading, a bold label or a paragraph), not merely occur
        start = r"^[#\s*-]*" + r"\s+".join(re.escape(w) for w in name.split())
        assert re.search(start, text, re.M), f'{where} names "{name}" in {page}, where nothing starts with it'


# a page's own section, named as `"Section" above`, `below, "Section"` or `("Section")`
_OWN = re.compile(
    r"\"(?P<a>[A-Z][^\"\n]{2,80})\"\s+(?:above|below)|(?:above|below),\s+\"(?P<b>[A-Z][^\"\n]{2,80})\""
    r"|\(\"(?P<c>[A-Z][^\"\n]{2,80})\"\)"
)
OWN_REFERENCES = [
    (page.name, m["a"] or m["b"] or m["c"])
    for page in sorted(DOCS.glob("*.md"))
    for m in _OWN.finditer(page.read_text(encoding="utf-8"))
]


def test_the_own_page_references_are_found():
    assert ("em-real.md", "Short logs") in OWN_REFERENCES
    assert ("em-real.md", "Misread barcodes") in OWN_REFERENCES


@pytest.mark.parametrize("page,name", OWN_REFERENCES, ids=[f"{p}:{n}" for p, n in OWN_REFERENCES])
def test_a_section_named_above_or_below_is_in_the_same_page(page, name):
    start = r"^[#\s*-]*" + r"\s+".join(re.escape(w) for w in name.split())
    assert re.search(start, (DOCS / page).read_text(encoding="utf-8"), re.M), f'{page} names "{name}", not in it'
