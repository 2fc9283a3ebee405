#!/usr/bin/env python3
"""Regenerate the documentation's parameter tables from the nodes' own ParamSpec lists (one source of truth).

Usage: .venv/bin/python scripts/gen_readme_params.py [--check]
Blocks between ``<!-- PARAMS module.path -->`` and ``<!-- /PARAMS -->`` in README.md and docs/*.md (the per-node
reference is docs/nodes.md, the simulated robot's nodes are in docs/simulator.md) are rewritten from
``module.path.PARAMS``; ``--check`` exits 1 if any file is out of date (tests/ros/test_readme_params.py).
"""

from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BLOCK = re.compile(r"(<!-- PARAMS ([\w.]+) -->\n)(.*?)(<!-- /PARAMS -->)", re.S)


def documents(root: Path | None = None) -> list[Path]:
    """Every Markdown file that may hold parameter tables: README.md and docs/*.md."""
    root = ROOT if root is None else root
    return [root / "README.md", *sorted((root / "docs").glob("*.md"))]


def render(text: str) -> str:
    from axis_ptz_ros2.nodes.common import params_markdown

    def repl(m: re.Match[str]) -> str:
        specs = importlib.import_module(m.group(2)).PARAMS
        return f"{m.group(1)}{params_markdown(specs)}\n{m.group(4)}"

    return BLOCK.sub(repl, text)


def main() -> int:
    stale, written = [], 0
    for doc in documents():
        text = doc.read_text(encoding="utf-8")
        new = render(text)
        written += len(BLOCK.findall(new))
        if new == text:
            continue
        stale.append(doc.relative_to(ROOT).as_posix())
        if "--check" not in sys.argv:
            doc.write_text(new, encoding="utf-8")
    if "--check" in sys.argv:
        if stale:
            print(f"parameter tables out of date in {', '.join(stale)}: run scripts/gen_readme_params.py")
            return 1
        return 0
    print(f"{written} parameter tables, {len(stale)} file(s) rewritten: {', '.join(stale) or 'none'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
