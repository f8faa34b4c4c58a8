"""The glossary's place in every page's navigation: docs/glossary.md, linked relative to where
the site stands when it lies in this repository (the committed reports under docs/results);
a site built elsewhere gets a copy beside its pages (a site opens from disk wherever it is
copied), its links into docs/ turned into the files' names in the repository."""
from __future__ import annotations

import os
import re
from pathlib import Path

from compare.results.store import atomic_write
from compare.site.questions_pages import REPO_DOCS

NAME = "glossary.md"
SOURCE = REPO_DOCS / NAME
LABEL = "Glossary"
# a Markdown link to a file (not a web address, not an anchor of the glossary itself)
_FILE_LINK = re.compile(r"\[([^\]]+)\]\((?!https?://|#)([^)\s#]+)(#[^)\s]*)?\)")


def inside(out: Path) -> bool:
    """The site stands in this repository, so docs/ is reachable by a relative link."""
    try:
        Path(out).resolve().relative_to(REPO_DOCS.parent)
    except ValueError:
        return False
    return True


def href(out: Path) -> str:
    """The glossary's link from a page of the site that stands at ``out``."""
    return os.path.relpath(SOURCE, Path(out).resolve()) if inside(out) else NAME


def standalone(text: str) -> str:
    """The glossary for a site outside the repository: each link to a docs file becomes its
    name (``docs/measurement.md``, section ``#two-regimes``) in code, which no reader follows."""
    def plain(m: re.Match[str]) -> str:
        path = os.path.normpath(os.path.join("docs", m.group(2))).replace(os.sep, "/")
        return f"{m.group(1)} (`{path}{m.group(3) or ''}` in the repository)"
    return _FILE_LINK.sub(plain, text)


def place(out: Path, into: Path) -> list[Path]:
    """Write the glossary's copy into ``into`` where the site at ``out`` cannot link docs/."""
    if inside(out):
        return []
    atomic_write(into / NAME, standalone(SOURCE.read_text(encoding="utf-8")))
    return [into / NAME]
