"""Import habits of ``vpr_core`` (issue 24, item 6): no module-level import cycle, few
function-level imports and only of optional heavy dependencies, no writes to ``os.environ``."""

from __future__ import annotations

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "vpr_core"

#: Top-level names that may be imported inside a function (optional or heavy dependencies);
#: ``tornado`` is dask.distributed's transport, imported only together with it.
ALLOWED_LOCAL = {
    "dask",
    "distributed",
    "tornado",
    "ipywidgets",
    "papermill",
    "nbformat",
    "nbclient",
    "jupytext",
    "IPython",
}
MAX_LOCAL = 15


def _modules() -> dict[str, Path]:
    """Dotted module name -> file, for every ``.py`` file in vpr_core."""
    out = {}
    for path in PKG.rglob("*.py"):
        parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _top_level(tree: ast.Module) -> list[ast.Import | ast.ImportFrom]:
    """Imports run when the module is imported (``if TYPE_CHECKING:`` blocks skipped)."""
    found: list[ast.Import | ast.ImportFrom] = []

    def visit(body: list[ast.stmt]) -> None:
        for node in body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                found.append(node)
            elif isinstance(node, ast.If):
                if "TYPE_CHECKING" not in ast.unparse(node.test):
                    visit(node.body)
                visit(node.orelse)
            elif isinstance(node, ast.Try):
                for block in (node.body, node.orelse, node.finalbody):
                    visit(block)
                for handler in node.handlers:
                    visit(handler.body)

    visit(tree.body)
    return found


def _graph() -> dict[str, set[str]]:
    """Module-level import edges among vpr_core modules (submodule -> own package ignored)."""
    mods = _modules()
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for name, path in mods.items():
        is_pkg = path.name == "__init__.py"
        for node in _top_level(ast.parse(path.read_text())):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                base = node.module or ""
                if node.level:
                    anchor = name.split(".")
                    anchor = anchor if is_pkg else anchor[:-1]
                    anchor = anchor[: len(anchor) - (node.level - 1)]
                    base = ".".join(anchor + ([base] if base else []))
                for alias in node.names:
                    sub = f"{base}.{alias.name}"
                    targets.append(sub if sub in mods else base)
            for target in targets:
                while target and target not in mods:  # ``import a.b.c`` of an attribute
                    target = target.rpartition(".")[0]
                if not target or target == name or name.startswith(target + "."):
                    continue
                graph[name].add(target)
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as a list of modules, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def dfs(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state and (found := dfs(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := dfs(node)):
            return found
    return None


def test_graph_sees_relative_imports():
    graph = _graph()
    assert "vpr_core.result" in graph["vpr_core.run"]
    assert "vpr_core.landmarks.schemes" in graph["vpr_core.run"]
    assert not any(m.startswith("vpr_study.cluster") for m in graph["vpr_core.run"])
    assert _cycle({"a": {"b"}, "b": {"a"}}) == ["a", "b", "a"]


def test_no_module_level_import_cycle():
    cycle = _cycle(_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def _local_imports() -> list[tuple[str, int, str]]:
    """``(file, line, top-level module)`` of every import inside a function body; a relative
    import of a ``vpr_core`` subpackage names it (``vpr_core.matching``)."""
    out = []
    for path in sorted(PKG.rglob("*.py")):
        package = list(path.relative_to(PKG.parent).parent.parts)
        for fn in ast.walk(ast.parse(path.read_text())):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                if isinstance(node, ast.Import):
                    names = [a.name.split(".")[0] for a in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level:
                    anchor = package[: len(package) - (node.level - 1)]
                    parts = anchor + (node.module or node.names[0].name).split(".")
                    names = [".".join(parts[:2])]
                elif isinstance(node, ast.ImportFrom):
                    names = [(node.module or "").split(".")[0]]
                else:
                    continue
                out += [(path.name, node.lineno, n) for n in names]
    return out


def test_function_level_imports_few_and_optional():
    local = sorted(set(_local_imports()))
    assert len(local) <= MAX_LOCAL, local
    bad = [x for x in local if x[2] not in ALLOWED_LOCAL]
    assert not bad, f"move these imports to module top: {bad}"


def _environ_writes(source: str) -> list[int]:
    """Line numbers where ``source`` writes the process environment."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        text = ""
        if isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign, ast.Delete)):
            targets = node.targets if isinstance(node, (ast.Assign, ast.Delete)) else [node.target]
            text = " ".join(ast.unparse(t) for t in targets if isinstance(t, ast.Subscript))
            if "environ[" in text:
                lines.append(node.lineno)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            owner = ast.unparse(node.func.value)
            writes = {"update", "pop", "setdefault", "popitem", "clear", "__setitem__"}
            if (owner.endswith("environ") and node.func.attr in writes) or (
                owner == "os" and node.func.attr in {"putenv", "unsetenv"}
            ):
                lines.append(node.lineno)
    return lines


def test_environ_write_detector():
    src = "import os\nos.environ['A'] = '1'\nos.environ.setdefault('B', '2')\nos.putenv('C', '')\n"
    assert _environ_writes(src) == [2, 3, 4]
    assert _environ_writes("import os\nx = os.environ.get('A')\n") == []


def test_no_library_writes_os_environ():
    bad = {
        str(p.relative_to(PKG)): found
        for p in sorted(PKG.rglob("*.py"))
        if (found := _environ_writes(p.read_text()))
    }
    assert not bad, f"pass settings via subprocess env= or papermill parameters: {bad}"


def test_pipeline_never_imports_the_study_tooling():
    """``vpr_core`` is the pipeline; ``vpr_study`` (CLI, runner, findings) sits on top of it."""
    bad = []
    for path in sorted(PKG.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                names = [node.module or ""]
            else:
                continue
            where = f"{path.relative_to(PKG)}:{node.lineno}"
            bad += [where for n in names if n.startswith("vpr_study")]
    assert not bad, f"vpr_core must not import vpr_study: {bad}"
    assert (PKG.parent / "vpr_study" / "cli.py").is_file()


def test_importing_every_core_module_loads_no_workbench_library():
    """Issue 52: ``vpr_core`` is the pipeline: importing all of it (a fresh interpreter) loads no
    plotting, notebook or cluster library."""
    import subprocess
    import sys

    code = (
        "import importlib, pkgutil, sys, vpr_core\n"
        "for m in pkgutil.walk_packages(vpr_core.__path__, 'vpr_core.'):\n"
        "    importlib.import_module(m.name)\n"
        "heavy = ('matplotlib', 'dask', 'distributed', 'ipywidgets', 'papermill', 'nbclient',\n"
        "         'nbformat', 'IPython', 'jupytext', 'vpr_study')\n"
        "print(sorted({k.split('.')[0] for k in sys.modules} & set(heavy)))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
