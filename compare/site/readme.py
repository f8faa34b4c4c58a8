"""README's generated blocks: the recommendation matrices, copied from the committed reports.

README.md holds ``<!-- BEGIN generated: PATH -->`` ... ``<!-- END generated -->`` blocks; PATH is
a generated file (a report's matrix.md) whose links are rewritten relative to README. The test
suite fails when a block differs from its file; ``python -m compare.site.readme`` rewrites them.
"""
from __future__ import annotations

import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BLOCK = re.compile(r"(<!-- BEGIN generated: (\S+) -->\n)(.*?)(<!-- END generated -->)", re.S)
LINK = re.compile(r"\]\((?!https?://|#|/)([^)]+)\)")


def content(path: Path, readme: Path) -> str:
    """The generated file's text with its relative links made relative to README's folder."""
    base = os.path.relpath(path.parent, readme.parent)
    text = path.read_text(encoding="utf-8")
    return LINK.sub(lambda m: f"]({Path(base, m.group(1)).as_posix()})", text).rstrip("\n") + "\n"


def expected(readme: Path = ROOT / "README.md") -> str:
    text = readme.read_text(encoding="utf-8")
    return BLOCK.sub(lambda m: m.group(1) + content(readme.parent / m.group(2), readme) + m.group(4), text)


def blocks(readme: Path = ROOT / "README.md") -> list[str]:
    return [m.group(2) for m in BLOCK.finditer(readme.read_text(encoding="utf-8"))]


def main(argv: list[str]) -> int:
    readme = ROOT / "README.md"
    new = expected(readme)
    if "--check" in argv:
        same = new == readme.read_text(encoding="utf-8")
        print("README's generated blocks are current" if same else "README's generated blocks differ")
        return 0 if same else 1
    readme.write_text(new, encoding="utf-8")
    print(f"rewrote {len(blocks(readme))} generated blocks in {readme}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
