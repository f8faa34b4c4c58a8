"""Pages as blocks, written twice: HTML (self-contained: inline CSS and a sorting script, relative
links only) and its Markdown twin for GitHub.

A page is a title and a list of blocks: ``H(text)``, ``P(text)``, ``Table(headers, rows)``,
``Figure(png, caption, command)``, ``Code(text)``, ``Items(texts)``, ``Raw(html, markdown)``.
Text may hold ``[label](href)`` links, ``**bold**`` and ``code`` spans; nothing else is markup.
"""
from __future__ import annotations

import dataclasses
import html
import re
from typing import Union

from compare.render.colors import band_css


@dataclasses.dataclass(frozen=True)
class H:
    text: str
    anchor: str = ""


@dataclasses.dataclass(frozen=True)
class P:
    text: str


@dataclasses.dataclass(frozen=True)
class Code:
    text: str


@dataclasses.dataclass(frozen=True)
class Items:
    texts: tuple[str, ...]


@dataclasses.dataclass(frozen=True)
class Table:
    headers: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    sortable: bool = True


@dataclasses.dataclass(frozen=True)
class Figure:
    png: str                      # relative to the page
    caption: str
    command: str = ""             # the command that reproduces the figure's data
    csv: str = ""                 # its data, relative to the page


@dataclasses.dataclass(frozen=True)
class Raw:
    html: str
    markdown: str


Block = Union[H, P, Code, Items, Table, Figure, Raw]

_INLINE = re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)|\*\*(.+?)\*\*|`([^`]+)`")


def inline_html(text: str) -> str:
    out, pos = [], 0
    for m in _INLINE.finditer(text):
        out.append(html.escape(text[pos:m.start()]))
        if m.group(1) is not None:
            href = m.group(2)
            out.append(f'<a href="{html.escape(href)}">{html.escape(m.group(1))}</a>')
        elif m.group(3) is not None:
            out.append(f"<strong>{html.escape(m.group(3))}</strong>")
        else:
            out.append(f"<code>{html.escape(m.group(4))}</code>")
        pos = m.end()
    out.append(html.escape(text[pos:]))
    return "".join(out)


_SITE_LINK = re.compile(r"\]\(([\w.-]+)\.html(#[\w-]+)?\)")


def md_links(text: str) -> str:
    """Links between the site's pages point at the Markdown twins (``x.html`` -> ``x.md``)."""
    return _SITE_LINK.sub(lambda m: f"]({m.group(1)}.md{m.group(2) or ''})", text)


def md_cell(text: str) -> str:
    return md_links(text).replace("|", "\\|").replace("\n", " ")


CSS = """
body{font:15px/1.45 system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0 auto;max-width:1280px;
padding:1em 2em;color:#1b1f24}
nav{border-bottom:1px solid #ccd;padding-bottom:.5em;margin-bottom:1em}nav a{margin-right:1em}
h1{font-size:1.6em;margin:.3em 0}h2{font-size:1.25em;margin-top:1.6em}
table{border-collapse:collapse;margin:.6em 0;font-size:14px}
th,td{border:1px solid #d0d7de;padding:3px 8px;text-align:left;vertical-align:top}
th{background:#f3f5f7}th.sort{cursor:pointer}td.num{text-align:right;font-variant-numeric:tabular-nums}
table#matrix td.cell{text-align:center;min-width:5.5em;font-variant-numeric:tabular-nums}
table#matrix td.cell span.variant{display:block;font-size:11px;font-weight:400;opacity:.85}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #e1e4e8}
figcaption{font-size:13px;color:#444}pre{background:#f6f8fa;padding:.5em;overflow-x:auto;font-size:13px}
code{font-size:13px}.legend span{display:inline-block;padding:1px 8px;margin-right:.4em}
""" + band_css() + "\n"

SORT_JS = """
document.querySelectorAll('table.sortable').forEach(function(t){
  t.querySelectorAll('th').forEach(function(th,i){
    th.classList.add('sort');th.title='sort';
    th.addEventListener('click',function(){
      var body=t.tBodies[0],rows=Array.from(body.rows),asc=th.dataset.asc!=='1';
      var key=function(r){var c=r.cells[i];var v=c?(c.dataset.v||c.textContent):'';
        var x=parseFloat(v);return isNaN(x)?v:x;};
      rows.sort(function(a,b){var x=key(a),y=key(b);
        if(typeof x===typeof y)return (x<y?-1:x>y?1:0)*(asc?1:-1);
        return (typeof x==='number'?-1:1)*(asc?1:-1);});
      rows.forEach(function(r){body.appendChild(r);});th.dataset.asc=asc?'1':'0';});
  });
});
"""

_NUMERIC = re.compile(r"^[\d.,]+(e[+-]?\d+)?(\s?\S+)?$")


def _td(cell: str) -> str:
    cls = ' class="num"' if _NUMERIC.match(cell.strip()) else ""
    return f"<td{cls}>{inline_html(cell)}</td>"


def block_html(b: Block) -> str:
    if isinstance(b, H):
        aid = f' id="{html.escape(b.anchor)}"' if b.anchor else ""
        return f"<h2{aid}>{inline_html(b.text)}</h2>"
    if isinstance(b, P):
        return f"<p>{inline_html(b.text)}</p>"
    if isinstance(b, Code):
        return f"<pre><code>{html.escape(b.text)}</code></pre>"
    if isinstance(b, Items):
        return "<ul>" + "".join(f"<li>{inline_html(t)}</li>" for t in b.texts) + "</ul>"
    if isinstance(b, Table):
        cls = ' class="sortable"' if b.sortable else ""
        head = "".join(f"<th>{inline_html(h)}</th>" for h in b.headers)
        body = "".join("<tr>" + "".join(_td(c) for c in row) + "</tr>" for row in b.rows)
        return f"<table{cls}><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
    if isinstance(b, Figure):
        extra = ""
        if b.csv:
            extra += f' <a href="{html.escape(b.csv)}">data (CSV)</a>'
        cmd = f"<pre><code>{html.escape(b.command)}</code></pre>" if b.command else ""
        return (f'<figure><img src="{html.escape(b.png)}" alt="{html.escape(b.caption)}">'
                f"<figcaption>{inline_html(b.caption)}{extra}</figcaption>{cmd}</figure>")
    if isinstance(b, Raw):
        return b.html
    raise TypeError(f"not a block: {b!r}")


def block_md(b: Block) -> str:
    if isinstance(b, H):
        return f"## {b.text}"
    if isinstance(b, P):
        return md_links(b.text)
    if isinstance(b, Code):
        return f"```\n{b.text}\n```"
    if isinstance(b, Items):
        return "\n".join(f"- {md_links(t)}" for t in b.texts)
    if isinstance(b, Table):
        lines = ["| " + " | ".join(md_cell(h) for h in b.headers) + " |",
                 "|" + "---|" * len(b.headers)]
        lines += ["| " + " | ".join(md_cell(c) for c in row) + " |" for row in b.rows]
        return "\n".join(lines)
    if isinstance(b, Figure):
        data = f" ([data]({b.csv}))" if b.csv else ""
        cmd = f"\n\n```\n{b.command}\n```" if b.command else ""
        return f"![{b.caption}]({b.png})\n\n*{md_links(b.caption)}*{data}{cmd}"
    if isinstance(b, Raw):
        return b.markdown
    raise TypeError(f"not a block: {b!r}")


def page_html(title: str, nav: list[tuple[str, str]], blocks: list[Block]) -> str:
    links = "".join(f'<a href="{html.escape(href)}">{html.escape(label)}</a>' for label, href in nav)
    body = "\n".join(block_html(b) for b in blocks)
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>{html.escape(title)}</title><style>{CSS}</style></head>\n<body>"
            f"<nav>{links}</nav><h1>{html.escape(title)}</h1>\n{body}\n"
            f"<script>{SORT_JS}</script></body></html>\n")


def page_md(title: str, nav: list[tuple[str, str]], blocks: list[Block]) -> str:
    links = md_links(" · ".join(f"[{label}]({href})" for label, href in nav))
    parts = [f"# {title}", links, *(block_md(b) for b in blocks)]
    return "\n\n".join(parts) + "\n"
