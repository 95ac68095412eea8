"""The README is the user's page and the documents speak of the product: short, its links alive."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]

#: words about how the product was made, not about the product (dates and commits say when instead)
NOT_ABOUT_THE_PRODUCT = re.compile(
    r"(first|second|third|[a-z]+teenth|[0-9]+th) session|issue [0-9]+|workplace", re.IGNORECASE
)


def test_readme_is_short_and_starts_with_the_two_commands():
    lines = (REPO / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 200, f"README.md has {len(lines)} lines; move detail to docs/"
    head = "\n".join(lines[:6])
    assert "./scripts/demo" in head and "./scripts/test" in head


def test_the_readmes_figures_are_a_short_table():
    """One line of figures a row; each figure's conditions, seeds and history live in docs/figures.md."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    section = text.split("## Headline figures", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| ") and not line.startswith("| what ")]
    assert 5 <= len(rows) <= 16, f"{len(rows)} rows of figures"
    long = [row[:60] for row in rows if len(row) > 240]
    assert long == [], f"rows past 240 characters (conditions go to docs/figures.md): {long}"
    assert "docs/figures.md" in section


def test_documents_speak_of_the_product():
    found = [
        f"{doc.relative_to(REPO)}:{i}: {line.strip()}"
        for doc in DOCS
        for i, line in enumerate(doc.read_text(encoding="utf-8").splitlines(), 1)
        if NOT_ABOUT_THE_PRODUCT.search(line)
    ]
    assert found == []


def test_relative_links_of_the_documents_lead_to_files():
    dead, checked = [], 0
    for doc in DOCS:
        for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", doc.read_text(encoding="utf-8")):
            checked += 1
            if not (doc.parent / target).exists():
                dead.append(f"{doc.relative_to(REPO)} -> {target}")
    assert checked >= 10  # the README's bench scripts and documents at least
    assert dead == []
