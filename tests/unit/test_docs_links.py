"""The README stays a newcomer's page and every relative link in it and in docs/*.md lands somewhere.

Links are checked the way GitHub renders them: the file (or folder) a relative link names must exist inside the
repository, and a ``#anchor`` must be the GitHub slug of a heading in the target Markdown file (or in the same file
for ``#anchor`` alone). Headings within one file must have distinct slugs, else a link lands on the first of them.
Fenced code blocks and inline code are not Markdown, so neither their ``#`` lines nor their brackets count.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

pytestmark = pytest.mark.unit

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
DOCS = sorted((ROOT / "docs").glob("*.md"))
README_MAX_LINES = 350

FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})")
HEADING = re.compile(r"^ {0,3}(#{1,6})[ \t]+(.*?)(?:[ \t]+#+)?[ \t]*$")
INLINE_CODE = re.compile(r"(`+)(.+?)\1")
LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]*)>?(?:\s+\"[^\"]*\")?\s*\)")


def prose_lines(text: str) -> list[str]:
    """The file's lines outside fenced code blocks (fenced lines come back empty, so numbering is kept)."""
    out, fence = [], ""
    for line in text.splitlines():
        m = FENCE.match(line)
        if fence:
            if m and m.group(1)[0] == fence[0] and len(m.group(1)) >= len(fence):
                fence = ""
            out.append("")
        elif m:
            fence = m.group(1)
            out.append("")
        else:
            out.append(line)
    return out


def github_slug(heading: str) -> str:
    """GitHub's anchor for a heading's text: rendered text, lower case, punctuation dropped, spaces → hyphens."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link or image in a heading: its text
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML
    text = text.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)  # letters, digits, '_', '-' and spaces survive
    return text.replace(" ", "-")


def slugs(path: Path) -> list[str]:
    """Every heading's anchor in document order, with GitHub's -1, -2 … for repeats."""
    seen: dict[str, int] = {}
    out = []
    for line in prose_lines(path.read_text(encoding="utf-8")):
        m = HEADING.match(line)
        if not m:
            continue
        base = github_slug(m.group(2))
        n = seen.get(base, 0)
        seen[base] = n + 1
        out.append(base if n == 0 else f"{base}-{n}")
    return out


def links(path: Path) -> list[tuple[int, str]]:
    """(line number, target) of every Markdown link and image in the file's prose."""
    found = []
    for no, line in enumerate(prose_lines(path.read_text(encoding="utf-8")), 1):
        line = INLINE_CODE.sub("", line)
        found += [(no, m.group(1)) for m in LINK.finditer(line)]
    return found


def broken_links(path: Path) -> list[str]:
    """What is wrong with the file's relative links, one line each ('' when all resolve)."""
    problems = []
    for no, target in links(path):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):  # https:, mailto: … : not ours to check
            continue
        where = f"{path.relative_to(ROOT)}:{no}: ({target})"
        file_part, _, anchor = target.partition("#")
        dest = (path.parent / file_part).resolve() if file_part else path
        if not dest.is_relative_to(ROOT):
            problems.append(f"{where} points outside the repository")
            continue
        if not dest.exists():
            problems.append(f"{where} names a file that does not exist")
            continue
        if anchor:
            if dest.suffix != ".md" or dest.is_dir():
                problems.append(f"{where} has an anchor into a file that is not Markdown")
            elif anchor not in slugs(dest):
                problems.append(f"{where}: no heading in {dest.relative_to(ROOT)} has the anchor #{anchor}")
    return problems


DOCUMENTS = [README, *DOCS]


@pytest.mark.parametrize("doc", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_and_anchor_resolves(doc: Path) -> None:
    problems = broken_links(doc)
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("doc", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_headings_have_distinct_anchors(doc: Path) -> None:
    bases = [
        github_slug(m.group(2)) for line in prose_lines(doc.read_text(encoding="utf-8")) if (m := HEADING.match(line))
    ]
    assert bases, f"{doc.name} has no heading"
    repeated = sorted({b for b in bases if bases.count(b) > 1})
    assert not repeated, f"{doc.name}: headings with the same anchor (links land on the first): {repeated}"


def test_the_readme_is_a_newcomer_s_page() -> None:
    text = README.read_text(encoding="utf-8")
    lines = text.count("\n") + (not text.endswith("\n"))
    assert lines <= README_MAX_LINES, (
        f"README.md has {lines} lines: move detail into docs/ (at most {README_MAX_LINES})"
    )
    anchors = slugs(README)
    for section in ("on-a-jazzy-robot", "without-ros-installed", "the-nodes-at-a-glance", "where-to-read-on"):
        assert section in anchors, f"README.md lacks the section #{section}"
    # the install part leads with the Jazzy robot, then the PyPI bootstrap
    assert anchors.index("on-a-jazzy-robot") < anchors.index("without-ros-installed")
    for command in ("./scripts/demo", "./scripts/test", "PIP_BREAK_SYSTEM_PACKAGES=1 rosdep install", "colcon build"):
        assert command in text, command
    for doc in DOCUMENTS:  # the old recipe: obsolete since the repository root is no package
        assert "colcon build --base-paths" not in doc.read_text(encoding="utf-8"), f"{doc.name}: plain colcon build"


def test_every_page_in_docs_is_linked_from_the_readme() -> None:
    targets = {(README.parent / t.partition("#")[0]).resolve() for _, t in links(README) if "://" not in t}
    unlinked = [d.name for d in DOCS if d.resolve() not in targets]
    assert not unlinked, f"README.md never links {unlinked}"


def test_the_checker_catches_what_it_claims_to(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The checker itself: a missing file, a wrong anchor, a repeated heading and code are told apart."""
    root = tmp_path
    (root / "docs").mkdir()
    (root / "docs" / "a.md").write_text(
        "# A page — with `code` and ×\n\n## Same\n\n## Same\n\n```\n# not a heading [x](nowhere.md)\n```\n",
        encoding="utf-8",
    )
    page = root / "README.md"
    page.write_text(
        "# R\n\n[ok](docs/a.md#a-page--with-code-and-) [ok](docs/a.md#same-1) [ok](#r) [web](https://x.y/#z)\n"
        "[missing](docs/b.md) [bad anchor](docs/a.md#not-a-heading) `[code](not/a/link.md)`\n",
        encoding="utf-8",
    )
    monkeypatch.setitem(globals(), "ROOT", root)
    assert slugs(root / "docs" / "a.md") == ["a-page--with-code-and-", "same", "same-1"]
    problems = broken_links(page)
    assert len(problems) == 2, problems
    assert "docs/b.md) names a file that does not exist" in problems[0]
    assert "no heading in docs/a.md has the anchor #not-a-heading" in problems[1]
