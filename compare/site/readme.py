"""README's generated blocks: the answers and the recommendation matrices, from the reports.

README.md holds ``<!-- BEGIN generated: SOURCE -->`` ... ``<!-- END generated -->`` blocks. A
SOURCE that is a path names a generated file (a report's matrix.md) whose links are rewritten
relative to README; ``answers REPORT...`` is the table of which framework for which job, derived
from the stores each report's site.json names (compare/site/answers.py); ``sitting``, in a later
sitting's README, is what that sitting shows (compare/site/sitting_readme.py). The test suite fails
when a block differs from its source; ``python -m compare.site.readme`` rewrites them all, and with
``--reports`` first rebuilds every committed report from the stores its site.json names (each one,
not only those a change was meant for: a shared page's wording reaches them all).
"""
from __future__ import annotations

import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BLOCK = re.compile(r"(<!-- BEGIN generated: (.+?) -->\n)(.*?)(<!-- END generated -->)", re.S)
LINK = re.compile(r"\]\((?!https?://|#|/)([^)]+)\)")
ANCHOR = re.compile(r"\]\(#([^)]+)\)")
ANSWERS = "answers"        # a block's source: `answers REPORT...`
SITTING = "sitting"        # a block's source: the sitting whose folder holds the file


def content(path: Path, readme: Path) -> str:
    """The generated file's first block (a matrix.md's table: README stays one screen per
    machine) with its relative links made relative to README's folder; a link to an anchor of
    the file (a far ratio's footnote, listed under the table) points into the file."""
    base = os.path.relpath(path.parent, readme.parent)
    text = path.read_text(encoding="utf-8").strip("\n").split("\n\n")[0]
    text = LINK.sub(lambda m: f"]({Path(base, m.group(1)).as_posix()})", text)
    own = Path(os.path.relpath(path, readme.parent)).as_posix()
    return ANCHOR.sub(lambda m: f"]({own}#{m.group(1)})", text) + "\n"


def source(spec: str, readme: Path) -> str:
    """A block's text from its source: a generated file, or the answers of the named reports."""
    words = spec.split()
    if words == [SITTING]:
        from compare.site import sitting_readme
        return sitting_readme.block(readme.parent)
    if words[0] == ANSWERS:
        from compare.site import answers
        return answers.table([readme.parent / w for w in words[1:]], readme)
    return content(readme.parent / spec, readme)


def expected(readme: Path = ROOT / "README.md") -> str:
    text = readme.read_text(encoding="utf-8")
    return BLOCK.sub(lambda m: m.group(1) + source(m.group(2), readme) + m.group(4), text)


def blocks(readme: Path = ROOT / "README.md") -> list[str]:
    return [m.group(2) for m in BLOCK.finditer(readme.read_text(encoding="utf-8"))]


def rebuild(manifest: Path, out: Path) -> None:
    """The report a site.json describes (its inputs, title and --against, as first built), into ``out``."""
    import json
    from compare import site
    how = json.loads(manifest.read_text(encoding="utf-8"))
    site.build([ROOT / p for p in how["inputs"]], out, how["title"], [ROOT / p for p in how["against"]])


def rebuild_reports(results: Path = ROOT / "docs" / "results") -> None:
    """Every committed report rebuilt as its site.json says, in place."""
    for manifest in sorted(results.glob("*/report/site.json")):
        rebuild(manifest, manifest.parent)
        print(f"rebuilt {manifest.parent.relative_to(ROOT)}")


def main(argv: list[str]) -> int:
    from compare.results import formats          # a program's start-up, as compare.cli.main's:
    from compare.stress.format import FORMAT as STRESS      # the answers read the stores' sweep
    from compare.sweep.format import FORMAT as SWEEP        # and stress records
    formats.register(SWEEP, STRESS)
    from compare.site import sitting_readme
    if "--reports" in argv and "--check" not in argv:
        rebuild_reports()
    stale = []
    for readme in [ROOT / "README.md", *sitting_readme.readmes(ROOT / "docs" / "results")]:
        new = expected(readme)
        if new == readme.read_text(encoding="utf-8"):
            continue
        stale.append(readme)
        if "--check" not in argv:
            readme.write_text(new, encoding="utf-8")
            print(f"rewrote {len(blocks(readme))} generated blocks in {readme.relative_to(ROOT)}")
    if "--check" in argv:
        print("generated blocks differ in " + ", ".join(str(p.relative_to(ROOT)) for p in stale) if stale
              else "every README's generated blocks are current")
        return 1 if stale else 0
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
