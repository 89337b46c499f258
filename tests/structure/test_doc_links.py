"""Every relative link (and #anchor) in the README, bench/README.md and docs/*.md leads somewhere: a file that
exists, and for a Markdown target with an anchor, a heading whose GitHub-style slug is that anchor."""

from __future__ import annotations

import re
from pathlib import Path

from tests.support.imports import ROOT

LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")
FENCE = re.compile(r"```.*?```", re.S)


def slugs(path: Path) -> set[str]:
    """GitHub-style heading anchors of a Markdown file (lower case, punctuation dropped, spaces -> '-')."""
    return {re.sub(r"[^\w\- ]", "", line.lstrip("#").strip().lower()).replace(" ", "-")
            for line in path.read_text(encoding="utf-8").splitlines() if line.startswith("#")}


def broken_links(files: list[Path]) -> tuple[int, list[str]]:
    """(relative links seen, the broken ones as 'file: target: why'); links inside code fences do not count."""
    n, bad = 0, []
    for f in files:
        for m in LINK.finditer(FENCE.sub("", f.read_text(encoding="utf-8"))):
            target = m.group(1)
            if re.match(r"[a-z]+:", target):          # http:, mailto: ...: not relative
                continue
            n += 1
            path, _, anchor = target.partition("#")
            dest = (f.parent / path).resolve() if path else f
            if not dest.exists():
                bad.append(f"{f.name}: {target}: no such file")
            elif anchor and dest.suffix == ".md" and anchor not in slugs(dest):
                bad.append(f"{f.name}: {target}: no such heading")
    return n, bad


def test_every_relative_link_resolves() -> None:
    files = [ROOT / "README.md", ROOT / "bench" / "README.md"] + sorted((ROOT / "docs").glob("*.md")) \
        + sorted((ROOT / "docs" / "history").glob("*.md"))
    n, bad = broken_links(files)
    assert n > 100, n
    assert not bad, "\n".join(bad)


def test_the_link_check_sees_a_missing_file_and_a_missing_heading(tmp_path: Path) -> None:
    (tmp_path / "there.md").write_text("# Where things are\n")
    doc = tmp_path / "x.md"
    doc.write_text("[a](there.md#where-things-are) [b](there.md#nowhere) [c](gone.md) [d](https://x.org/y)\n"
                   "```\n[e](gone-too.md)\n```\n")
    n, bad = broken_links([doc])
    assert n == 3 and bad == ["x.md: there.md#nowhere: no such heading", "x.md: gone.md: no such file"], bad
