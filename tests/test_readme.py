"""Tests of the README's newcomer path: the CI runs its test command, its links resolve."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _quick_start() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return text.split("## Quick start", 1)[1].split("\n## ", 1)[0]


def _commands(block: str) -> list[str]:
    return [ln.strip() for ln in block.splitlines() if ln.strip() and not ln.strip().startswith("#")]


def test_ci_runs_exactly_the_readme_test_command():
    """.ci/run's command is the Quick start's test command, character for character."""
    blocks = re.findall(r"```bash\n(.*?)```", _quick_start(), flags=re.S)
    commands = [c for b in blocks for c in _commands(b)]
    assert len(commands) == 2 and "fusion demo" in commands[0] and "pytest" in commands[1]
    ci = _commands((ROOT / ".ci" / "run").read_text(encoding="utf-8"))
    assert ci[-1] == commands[1]


def _anchor(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def test_readme_and_docs_links_resolve():
    """Every relative link of README.md and docs/*.md names a file of the repository or a heading."""
    for doc in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        text = doc.read_text(encoding="utf-8")
        anchors = {_anchor(h) for h in re.findall(r"^#+ (.+)$", text, flags=re.M)}
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"[a-z]+://", target):
                continue
            path, _, anchor = target.partition("#")
            if path:
                assert (doc.parent / path).exists(), f"{doc.name}: link to missing {target}"
            elif anchor:
                assert anchor in anchors, f"{doc.name}: no heading for #{anchor}"


def test_readme_names_no_notes_outside_the_repository():
    """The README points at no design notes or shared folders that are not in the repository."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "design notes" not in text and "../shared" not in text
