"""The README and docs/ as a newcomer reads them: every relative link lands on a file (and a
heading, when it names one), and every ``./pppbot VERB`` the README shows exists."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), ROOT / "ARCHITECTURE.md"]
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    return {slug(line.lstrip("#")) for line in page.read_text().splitlines() if line.startswith("#")}


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves(page: Path) -> None:
    broken = []
    for target in LINK.findall(page.read_text()):
        if re.match(r"[a-z]+://", target) or target.startswith("mailto:"):
            continue
        path, _, anchor = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        if not file.exists():
            broken.append(f"{target}: no such file")
        elif anchor and file.suffix == ".md" and anchor not in anchors(file):
            broken.append(f"{target}: no heading '#{anchor}' in {file.name}")
    assert not broken, f"{page.name}: " + "; ".join(broken)


def test_the_readme_is_a_guide_not_a_reference() -> None:
    assert len((ROOT / "README.md").read_text().splitlines()) <= 250


def test_every_verb_the_readme_shows_exists() -> None:
    verbs = sorted(set(re.findall(r"\./pppbot ([a-z_]+)", (ROOT / "README.md").read_text())))
    assert {"launch_sim", "map_saver", "nav", "bag", "eval"} <= set(verbs)
    for verb in verbs:
        result = subprocess.run([str(ROOT / "pppbot"), verb, "--help"], capture_output=True, text=True, timeout=120)
        assert result.returncode == 0 and verb in result.stdout + result.stderr, (verb, result.stderr)
