"""The prose of the code says what it is and why, not its history: no issue numbers in src/, tests/, docs/ or the
README (history goes in CHANGELOG.md and the commit messages), and no citation of notes outside the repository,
which a reader of a clone cannot open (a fact belongs in docs/, a V+ behaviour cites the manual's section)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
WORD = "issue"
ISSUE = re.compile(rf"\b[{WORD[0].upper()}{WORD[0]}]{WORD[1:]}s? (?:\d+|[A-Z]{{1,2}})\b|\(#\d+\)")
OUTSIDE = re.compile(r"\.\./shared|\bFACTS\.md\b|\bARCHITECTURE\.md\b|\bSTYLE\.md\b")
SUFFIXES = {".py", ".md", ".toml", ".json", ".yml", ".yaml", ".V2", ".txt", ".cfg", ".ini"}

NOT_YET: tuple[str, ...] = ()


def findings(text: str) -> list[str]:
    return [m.group(0) for pattern in (ISSUE, OUTSIDE) for m in pattern.finditer(text)]


def test_no_issue_numbers_and_no_notes_outside_the_repository():
    said = ["a fix (" + WORD + " 11)", WORD.title() + " 24: why", "as in " + WORD + " AA item 6", "see (#" + "12)",
            "(" + "FACTS" + ".md)", ".." + "/shared/notes"]
    assert all(findings(s) for s in said)
    assert findings("a tissue 3 mm thick, the issuer 5, see #12 in the table, an AA battery") == []

    found = []
    for top in ("src", "tests", "docs", "benchmarks", "editors", "vplus", "examples", "README.md"):
        for path in sorted((ROOT / top).rglob("*")) if (ROOT / top).is_dir() else [ROOT / top]:
            rel = path.relative_to(ROOT).as_posix()
            if not path.is_file() or path.suffix not in SUFFIXES or rel.startswith(NOT_YET) or "__pycache__" in rel:
                continue
            for n, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
                found += [f"{rel}:{n}: {hit}" for hit in findings(line)]
    assert found == [], "history or outside notes in the prose:\n" + "\n".join(found)
