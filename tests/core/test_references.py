"""Every citation in the repository resolves inside the repository.

Code and docs cite sources as ``docs/references.md §N``; each such N must be a section heading
(``## §N …``) of that file, and every ``docs/….md`` path named anywhere must exist. Nothing may
point at briefing files outside the repository.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
REFERENCES = ROOT / "docs" / "references.md"
TEXT_SUFFIXES = {".py", ".md", ".toml", ".sh", ".js", ".yaml", ".yml", ".json", ".txt", ".cfg", ".html"}
# "docs/references.md" then, possibly across a line break inside a comment or docstring, "§N".
CITATION = re.compile(r"docs/references\.md[\s#*(]*§(\d+)")
DOC_PATH = re.compile(r"\bdocs/([\w./-]+?\.md)\b")
# Files that live outside the repository and must never be named by it.
OUTSIDE = re.compile(r"REFERENCES\.md|DESIGN\.md|\.\./shared\b|shared/(?:reviews|seeds)\b")


def _tracked_text_files() -> list[Path]:
    try:
        out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: the citation check reads the tracked files")
    names = [ROOT / n for n in out.splitlines()]
    return [p for p in names if p.is_file() and (p.suffix in TEXT_SUFFIXES or p.name == "Makefile")]


def _sections() -> set[int]:
    return {int(m) for m in re.findall(r"^## §(\d+)\b", REFERENCES.read_text(encoding="utf-8"), re.M)}


def test_references_has_numbered_sections():
    sections = _sections()
    assert sections, f"{REFERENCES} has no '## §N' headings"
    assert sections == set(range(1, max(sections) + 1)), f"section numbers have gaps: {sorted(sections)}"


def test_every_citation_names_an_existing_section():
    sections = _sections()
    bad = []
    for path in _tracked_text_files():
        text = path.read_text(encoding="utf-8", errors="replace")
        for m in CITATION.finditer(text):
            if int(m.group(1)) not in sections:
                line = text.count("\n", 0, m.start()) + 1
                bad.append(f"{path.relative_to(ROOT)}:{line}: §{m.group(1)}")
    assert not bad, "citations of sections that docs/references.md does not have:\n" + "\n".join(bad)


def test_every_named_doc_exists():
    missing = []
    for path in _tracked_text_files():
        text = path.read_text(encoding="utf-8", errors="replace")
        for m in DOC_PATH.finditer(text):
            if not (ROOT / "docs" / m.group(1)).is_file():
                line = text.count("\n", 0, m.start()) + 1
                missing.append(f"{path.relative_to(ROOT)}:{line}: docs/{m.group(1)}")
    assert not missing, "docs named but not in the repository:\n" + "\n".join(missing)


def test_nothing_points_outside_the_repository():
    this = Path(__file__).resolve()
    hits = []
    for path in _tracked_text_files():
        if path.resolve() == this:
            continue
        for no, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            if OUTSIDE.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{no}: {line.strip()}")
    assert not hits, "references to files outside the repository:\n" + "\n".join(hits)
