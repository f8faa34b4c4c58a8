"""The layering the code promises, checked on its source (``ast``, nothing imported):

  * a scenario knows nothing of frameworks or of the suites: no module under scenarios/ imports
    ``backends`` or ``compare``;
  * no import cycle among the project's own modules (backends/, scenarios/, compare/). Imports
    at any level count, those inside functions included, so a cycle cannot hide behind a lazy
    import; importing ``a.b.c`` also runs ``a`` and ``a.b``, so those count as well (except a
    package of the importer's own, which is already running). Third-party imports (a framework,
    matplotlib) are not the project's and never count.
"""
from __future__ import annotations

import ast
from pathlib import Path

from conftest import ROOT

PACKAGES = ("backends", "scenarios", "compare")


def project_modules() -> dict[str, Path]:
    """Dotted name -> source file of every module of the project's packages."""
    found = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            found[".".join(parts)] = path
    return found


def imported_names(name: str, path: Path) -> set[str]:
    """Dotted names ``name``'s source imports, anywhere in it; ``from X import Y`` gives X.Y
    (Y may be a module) and X."""
    is_package = path.name == "__init__.py"
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base[:len(base) - node.level + (1 if is_package else 0)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            out.add(target)
            out.update(f"{target}.{a.name}" for a in node.names)
    return out


def graph() -> dict[str, set[str]]:
    """Module -> the project's modules that importing it runs (directly)."""
    mods = project_modules()
    edges: dict[str, set[str]] = {}
    for name, path in mods.items():
        own = {".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 2)}
        deps = set()
        for target in imported_names(name, path):
            parts = target.split(".")
            for i in range(1, len(parts) + 1):       # the module and the packages it runs
                prefix = ".".join(parts[:i])
                if prefix in mods and prefix not in own:
                    deps.add(prefix)
        edges[name] = deps
    return edges


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v); on.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop(); on.discard(w); comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in edges[v]:
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def test_scenarios_know_no_framework_and_no_suite():
    bad = []
    for name, path in project_modules().items():
        if name.split(".")[0] != "scenarios":
            continue
        for target in imported_names(name, path):
            if target.split(".")[0] in ("backends", "compare"):
                bad.append(f"{path.relative_to(ROOT)} imports {target}")
    assert not bad, "a scenario holds physics only:\n" + "\n".join(sorted(bad))


def test_no_import_cycle():
    found = cycles(graph())
    assert not found, "import cycles among the project's modules:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_the_checks_see_a_cycle_and_a_lazy_import(tmp_path):
    """The checker itself: a cycle held together by an import inside a function is found."""
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles(edges) == [["a", "b", "c"]]
    src = tmp_path / "m.py"
    src.write_text("def f():\n    from . import sibling\n    import backends.numpy\n")
    assert {"scenarios.sibling", "backends.numpy"} <= imported_names("scenarios.m", src)


# compare/'s stages, lowest first: a module imports only from its own stage and those before it
# (docs/architecture.md, "The folders"). The top modules (the cell, options, atomic files) are
# the vocabulary every stage shares; cli is the command line above everything.
STAGES = ("compare.spec compare.options compare.files", "compare.results", "compare.measuring",
          "compare.running", "compare.render", "compare.sweep compare.stress", "compare.planning",
          "compare.site", "compare.suites", "compare.cli compare.__main__ compare")

def stage(module: str) -> int | None:
    """The stage of a compare module (None: not compare's)."""
    best = None
    for i, names in enumerate(STAGES):
        for prefix in names.split():
            if module == prefix or module.startswith(prefix + "."):
                if best is None or len(prefix) > best[1]:
                    best = (i, len(prefix))
    return best[0] if best is not None else None


def test_compare_imports_only_downward():
    up = []
    for name, deps in graph().items():
        here = stage(name)
        if here is None:
            continue
        for dep in deps:
            there = stage(dep)
            if there is not None and there > here and dep != "compare":
                up.append(f"{name} ({STAGES[here].split()[0]}) imports {dep} ({STAGES[there].split()[0]})")
    assert not up, "an import runs back up the stages:\n" + "\n".join(sorted(up))


def test_every_compare_module_has_a_stage():
    assert [m for m in project_modules() if m.startswith("compare") and stage(m) is None] == []


def own_test(module: Path, names: set[str]) -> bool:
    """Whether ``module`` (under compare/) has a test file of its own name; where two modules share
    a name, the test's name carries its folder (test_topic_saxpy, test_figure_saxpy, ...)."""
    folder = module.parent.name
    prefixes = ("", f"{folder}_", f"{folder.removesuffix('s')}_")     # points_, topic_, figure_
    return any(f"test_{p}{module.stem}.py" in names for p in prefixes)


def test_every_compare_module_has_its_own_test_file_and_basenames_are_unique():
    tests = sorted((ROOT / "tests").rglob("test_*.py"))
    names = [t.name for t in tests]
    twice = sorted({n for n in names if names.count(n) > 1})
    assert not twice, f"pytest collects one basename once (no __init__.py in tests/): {twice}"
    missing = [str(m.relative_to(ROOT)) for m in sorted((ROOT / "compare").rglob("*.py"))
               if m.name not in ("__init__.py", "__main__.py") and not own_test(m, set(names))]
    assert not missing, f"modules without a test file of their own name: {missing}"


def test_modules_stay_small_and_the_readme_a_landing_page():
    """The guide's sizes: a module of at most 400 lines (source and tests), a README under 120
    (issue 58: the answer on the first screen; its sentences: tests/site/test_readme.py)."""
    sources = [p for d in (*PACKAGES, "tests") for p in sorted((ROOT / d).rglob("*.py"))]
    long = [f"{p.relative_to(ROOT)}: {n}" for p in sources
            if (n := len(p.read_text().splitlines())) > 400]
    assert not long, f"modules over 400 lines: {long}"
    assert len((ROOT / "README.md").read_text().splitlines()) < 120
