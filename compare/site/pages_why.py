"""Why a cell is far behind its row's leader, in one line read from its records: what the slow
port does differently (a host loop over the steps and its launches per call, eager operations,
a host that is busy for the whole call, a first call that compiles for seconds, the states a
gradient keeps), each fact a field of the record's ``info`` or ``time`` block, never typed here.
"""
from __future__ import annotations

import dataclasses
import html
import re

from compare.results.record import Record
from compare.site import data, fmt, matrix
from compare.site.data import Machine
from compare.site.matrix import Cell, Row
from compare.site.render import inline_html

WHY_ABOVE = 20.0       # a ratio above this carries its reason on the row's page
HOST_BOUND = 0.9       # issuing a call takes at least this share of its time: host-bound
HOST_LOOP = 10         # a function the host profile finds run this often per call: a loop on the host

# info fields that say how a port runs, in the order a reason names them: (field, words)
TIME_INFO = (("loop", "loop: {}"), ("execution", "execution: {}"), ("gradient", "gradient: {}"),
             ("ad_stack", "adstack: {}"))
MEMORY_INFO = (("state_layout", "states kept as {}"), ("states_kept_per_trajectory", "{} states kept per trajectory"),
               ("ad_stack_size", "adstack of {} entries"), ("ad_stack", "adstack: {}"), ("tape", "tape: {}"),
               ("gradient", "gradient: {}"))


def _launches(r: Record) -> str:
    """Kernel launches per call, from the port's own count (per step, per iteration, per run)."""
    info, p = r.info or {}, r.params or {}
    per_step, steps = data.num(info.get("kernels_per_step")), data.num(p.get("steps"))
    if per_step and steps:
        return f"{per_step:g} kernel launch{'es' if per_step != 1 else ''} per step × {steps:g} steps = " \
               f"{per_step * steps:,.0f} per call"
    per_iter, iters = data.num(info.get("launches_per_iteration")), data.num(p.get("iters"))
    if per_iter and iters:
        return f"{per_iter:g} launch{'es' if per_iter != 1 else ''} per descent iteration × {iters:g} = " \
               f"{per_iter * iters:,.0f} per call"
    per_run = data.num(info.get("launches_per_run"))
    return f"{per_run:g} launch{'es' if per_run != 1 else ''} per call" if per_run else ""


def _host(r: Record) -> list[str]:
    """The host's share of a call (time.throughput.host_s), and its most-called function."""
    t = r.time
    thr = t.throughput if t else None
    host, per = (data.num(thr.host_s), data.num(thr.median_s)) if thr else (None, None)
    out = []
    if host is not None and per and host / per >= HOST_BOUND:
        out.append(f"host-bound: issuing a call takes {fmt.pct(min(host / per, 1.0))} of its time")
    profile = t.host_profile if t else None
    top = [f for f in (profile.top if profile else None) or () if (data.num(f.calls) or 0) >= HOST_LOOP]
    if top:     # the loop that costs the most: the largest cumulative time
        f = max(top, key=lambda f: data.num(f.cumulative_s) or 0)
        out.append(f"`{f.function}` runs {data.num(f.calls):g}× per call (host profile)")
    return out


def _fields(r: Record, keys: tuple[tuple[str, str], ...]) -> list[str]:
    info = r.info or {}
    return [words.format(info[k]) for k, words in keys if info.get(k) not in (None, "", False)]


def facts(r: Record, unit: str, leader: bool = False) -> list[str]:
    """What one record says about how its port ran, for a row in ``unit``; for the leader, only
    how it is built (its loop and launches; what it keeps), the contrast a reader needs."""
    if unit == "B":
        return _fields(r, MEMORY_INFO[:-1] if leader else MEMORY_INFO)
    if leader:
        return [x for x in [*_fields(r, TIME_INFO[:1]), _launches(r)] if x]
    return [x for x in [*_fields(r, TIME_INFO[:1]), _launches(r), *_fields(r, TIME_INFO[1:]), *_host(r)] if x]


def first_result(recs: list[Record]) -> list[str]:
    """The time to first result of several scenarios: the first calls' sum and the largest."""
    firsts = [(v, r.scenario) for r in recs if r.time and (v := data.num(r.time.first_call_s)) is not None]
    setup = sum((data.num(r.time.setup_s) if r.time else None) or 0.0 for r in recs)
    if not firsts:
        return []
    big = max(firsts)
    out = [f"first calls (compile or trace, and the call) {fmt.seconds(sum(v for v, _ in firsts))}, the "
           f"largest {fmt.seconds(big[0])} ({big[1]})", f"set-up {fmt.seconds(setup)}"]
    compiled = next((str((r.info or {})["compiled"]) for r in recs if (r.info or {}).get("compiled")), "")
    return out + ([f"compiled with {compiled}"] if compiled else [])


def _records(row: Row, m: Machine, fw: str, variant: str) -> list[Record]:
    key = row.rule.key
    recs = matrix.all_defaults(m, row.device) if key == "cpu" else row.rule.pick(m, row.device)
    return [r for r in recs if r.backend == fw and r.variant == (variant or "default") and r.status == "ok"]


def reason(row: Row, m: Machine, c: Cell) -> str:
    """One line: the far cell's facts, then the leader's where its records say something."""
    def said(fw: str, variant: str, leader: bool = False) -> list[str]:
        recs = _records(row, m, fw, variant)
        if row.rule.key == "compile":
            return first_result(recs)[:2 if leader else 3]
        return facts(recs[0], row.rule.unit, leader) if len(recs) == 1 else []
    mine = said(c.framework, c.variant)
    if not mine:
        return ""
    lead = row.cells[row.top] if row.top else None
    theirs = said(lead.framework, lead.variant, True) if lead is not None else []
    text = "; ".join(mine)
    if lead is not None and theirs:
        name = lead.framework + (f" {lead.variant}" if lead.winner_not_default else "")
        text += f" (leader {name}: {'; '.join(theirs)})"
    return text


def far(c: Cell) -> bool:
    """A ranked cell beyond WHY_ABOVE: it carries its reason (or says it has none)."""
    return c.ratio is not None and c.ratio > WHY_ABOVE and not c.reference


def explain(row: Row, m: Machine) -> Row:
    """The row with each ranked cell beyond WHY_ABOVE given its reason."""
    cells = {f: dataclasses.replace(c, why=reason(row, m, c)) if far(c) else c for f, c in row.cells.items()}
    return dataclasses.replace(row, cells=cells)


def lines(row: Row) -> list[str]:
    """The row's far cells with their reasons, farthest first, for its page."""
    far = sorted((c for c in row.cells.values() if c.why), key=lambda c: -(c.ratio or 0.0))
    return [f"**{c.framework} {fmt.ratio(c.ratio or 0.0)}**"
            + (f" ({c.variant} variant)" if c.winner_not_default else "") + f": {c.why}." for c in far]


# ---- the matrix's footnotes: each far cell's mark, and its reason listed under the matrix --------
@dataclasses.dataclass(frozen=True)
class Note:
    n: int                # the mark, counted over the matrix row by row, column by column
    row: Row
    cell: Cell


def slug(text: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", text.lower()).replace(" ", "-")


def key_of(m: Machine) -> str:
    """The machine's short name in the footnotes' ids: its store's folder (``h100``), else its name."""
    return slug(m.sources[0].parent.name if m.sources else m.name())


def notes(rows: list[Row], frameworks: list[str]) -> list[Note]:
    far_cells = [(r, c) for r in rows for f in frameworks if (c := r.cells.get(f)) is not None and far(c)]
    return [Note(i, r, c) for i, (r, c) in enumerate(far_cells, start=1)]


def anchor(n: Note, key: str) -> str:
    """The footnote's id; ``key`` (the machine) keeps two matrices on one page (README) apart."""
    return f"why-{key}-{n.n}" if key else f"why-{n.n}"


NO_REASON = "its records say nothing of how the port ran (its figures: the row's page)"


def note_text(n: Note) -> str:
    """One footnote: the mark, the cell, and the reason from its records (or that there is none)."""
    c = n.cell
    who = f"{c.framework} {fmt.ratio(c.ratio or 0.0)}" + (f" ({c.variant})" if c.winner_not_default else "")
    return f"**{n.n}** {who}: {c.why or NO_REASON}."


def row_link(r: Row, md: bool, prefix: str = "") -> str:
    """The row's question, linked to its section on its page (``prefix``: the pages' folder)."""
    where = f"{prefix}{r.rule.page}.md#{slug(r.rule.question)}" if md else f"{r.rule.page}.html#{r.rule.key}"
    return f"[{r.rule.question}]({where})"


def by_row(ns: list[Note]) -> list[list[Note]]:
    """The footnotes grouped by row, in the matrix's order: one line each (README stays short)."""
    groups: dict[int, list[Note]] = {}
    for n in ns:
        groups.setdefault(id(n.row), []).append(n)
    return list(groups.values())


HEAD = f"Ratios above {WHY_ABOVE:g}× and why, from the records (numbered as marked in the matrix):"


def mark_md(n: Note, key: str) -> str:
    return f"<sup>[{n.n}](#{anchor(n, key)})</sup>"


def mark_html(n: Note, key: str) -> str:
    return f'<sup><a href="#{anchor(n, key)}">{n.n}</a></sup>'


def notes_md(ns: list[Note], key: str, prefix: str = "") -> str:
    if not ns:
        return ""
    return "\n".join([HEAD, ""] + [
        f"- {row_link(g[0].row, True, prefix)}: " + " ".join(f'<a id="{anchor(n, key)}"></a>{note_text(n)}' for n in g)
        for g in by_row(ns)])


def notes_html(ns: list[Note], key: str) -> str:
    if not ns:
        return ""
    items = "".join(f"<li>{inline_html(row_link(g[0].row, False) + ':')} " + " ".join(
        f'<span id="{html.escape(anchor(n, key))}">{inline_html(note_text(n))}</span>' for n in g) + "</li>"
        for g in by_row(ns))
    return f'<p class="why">{html.escape(HEAD)}</p><ul class="why">{items}</ul>'
