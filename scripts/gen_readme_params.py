#!/usr/bin/env python3
"""Regenerate the README's parameter tables from the nodes' own ParamSpec lists (one source of truth).

Usage: .venv/bin/python scripts/gen_readme_params.py [--check]
Blocks in README.md between ``<!-- PARAMS module.path -->`` and ``<!-- /PARAMS -->`` are rewritten from
``module.path.PARAMS``; ``--check`` exits 1 if the README is out of date (tests/ros/test_readme_params.py).
"""

from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"
BLOCK = re.compile(r"(<!-- PARAMS ([\w.]+) -->\n)(.*?)(<!-- /PARAMS -->)", re.S)


def render(text: str) -> str:
    from axis_ptz_ros2.nodes.common import params_markdown

    def repl(m: re.Match[str]) -> str:
        specs = importlib.import_module(m.group(2)).PARAMS
        return f"{m.group(1)}{params_markdown(specs)}\n{m.group(4)}"

    return BLOCK.sub(repl, text)


def main() -> int:
    text = README.read_text(encoding="utf-8")
    new = render(text)
    if "--check" in sys.argv:
        if new != text:
            print("README.md parameter tables are out of date: run scripts/gen_readme_params.py")
            return 1
        return 0
    README.write_text(new, encoding="utf-8")
    print(f"README.md: {len(BLOCK.findall(new))} parameter tables written")
    return 0


if __name__ == "__main__":
    sys.exit(main())
