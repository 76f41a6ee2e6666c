"""Size of ``vpr_core`` by kind of line: code, docstring, comment, blank, per package.

Issue 16 measures the package with ``find vpr_core -name '*.py' | xargs wc -l``; this script
prints the same total and splits it, so a reader sees what the lines are: statements, the
docstrings the project keeps on every public function (Google style, with shapes), comments and
blank lines. Docstring lines are the lines of a module, class or function docstring.

Issue 31 adds the guard share: guard lines (``raise`` statements, and the test of an ``if``
whose only body is a ``raise``) over code lines; the anchors (hloc, LightGlue, kornia) are 1-7%.
It also counts how values flow (DESIGN.md habit 5): the functions with more than 8 explicit
parameters, and in how many signatures each option the issue names appears (target: 3).

Issues 47, 52 and 59 add what a reader meets: the one flat face (``vpr_core.__all__``: what code
outside the package imports; target about 80 names), the distinct core names ``vpr_study`` uses,
the imports by callers that reach past a face (target 0: ``vpr_study``, the notebooks, the starter
and README / docs code import ``vpr_core``, ``vpr_study`` and ``vpr_study.viz`` only; tests and
benchmarks may import modules), the modules without ``__all__``, and the rules raised from more
than one site (raise statements grouped by their message with the placeholders blanked; target
0), with the near-duplicate messages (shared words, for reading) beside them. ``--names`` prints
the face as docs/ARCHITECTURE.md lists it.

Usage::

    .venv/bin/python benchmarks/code_size.py            # per package, then the total
    .venv/bin/python benchmarks/code_size.py --files    # per file
    .venv/bin/python benchmarks/code_size.py --root vpr_study   # the study's tooling
    .venv/bin/python benchmarks/code_size.py --rules    # every rule raised from > 1 site
    .venv/bin/python benchmarks/code_size.py --names    # the face, by module (markdown)
"""

from __future__ import annotations

import argparse
import ast
import json
import re
from collections import Counter, defaultdict
from pathlib import Path

KINDS = ("code", "docstring", "comment", "blank")
GUARD = "guard"
DOC_OWNERS = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)


def line_kinds(source: str) -> Counter:
    """Counts of :data:`KINDS` over the lines of one Python source."""
    doc_lines: set[int] = set()
    for node in ast.walk(ast.parse(source)):
        body = getattr(node, "body", None)
        if (
            isinstance(node, DOC_OWNERS)
            and body
            and isinstance(body[0], ast.Expr)
            and isinstance(body[0].value, ast.Constant)
            and isinstance(body[0].value.value, str)
        ):
            doc_lines.update(range(body[0].lineno, body[0].end_lineno + 1))
    guards = guard_lines(source)
    counts: Counter = Counter({k: 0 for k in (*KINDS, GUARD)})
    for number, line in enumerate(source.splitlines(), 1):
        text = line.strip()
        kind = (
            "docstring"
            if number in doc_lines
            else "blank"
            if not text
            else "comment"
            if text.startswith("#")
            else "code"
        )
        counts[kind] += 1
        counts[GUARD] += kind == "code" and number in guards
    return counts


def guard_lines(source: str) -> set[int]:
    """Line numbers of ``raise`` statements and of ``if`` tests whose only body is a raise."""
    lines: set[int] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Raise):
            lines.update(range(node.lineno, node.end_lineno + 1))
        elif (
            isinstance(node, ast.If) and len(node.body) == 1 and isinstance(node.body[0], ast.Raise)
        ):
            lines.update(range(node.lineno, node.test.end_lineno + 1))
    return lines


#: The options issue 31 counts in signatures (an option should appear in at most 3).
OPTIONS = (
    "protocol",
    "tolerance",
    "sigma",
    "input_size",
    "spatial",
    "soft_nms_iou",
    "weighting",
    "pooling",
    "iou_threshold",
)
MAX_PARAMETERS = 8


def signatures(root: Path) -> tuple[list[tuple[int, str]], Counter]:
    """``([(parameters, "file:line name")] over MAX_PARAMETERS, {option: signatures})``."""
    wide, options = [], Counter()
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                a = node.args
                names = [x.arg for x in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
                names = [n for n in names if n not in ("self", "cls")]
                if len(names) > MAX_PARAMETERS:
                    wide.append((len(names), f"{path.relative_to(root)}:{node.lineno} {node.name}"))
                options.update(n for n in names if n in OPTIONS)
    return sorted(wide, reverse=True), options


def module_name(path: Path, root: Path) -> str:
    """``vpr_core.matching.core`` for ``<root>/matching/core.py`` (``root`` named ``vpr_core``)."""
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def declared_all(tree: ast.Module) -> list[str] | None:
    """The literal ``__all__`` of a module, or None."""
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else []
        if isinstance(node, ast.AnnAssign):
            targets = [node.target]
        if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
            return [e.value for e in getattr(node.value, "elts", []) if isinstance(e, ast.Constant)]
    return None


def face(root: Path) -> dict:
    """What issues 47, 52 and 59 count: ``public`` ``[(module, name)]`` (functions and classes
    outside the package's ``__init__`` files), ``no_all`` (modules without ``__all__``), ``all``
    (each module's ``__all__``), ``faces`` (the one face: the top-level ``__init__.py``'s
    ``__all__``, what callers import) and ``indexes`` (each subpackage's ``__all__``: its stage's
    names, for the package's own modules, tests and benchmarks)."""
    out: dict = {"public": [], "no_all": [], "all": {}, "faces": {}, "indexes": {}}
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        mod = module_name(path, root)
        names = declared_all(tree)
        if names is None:
            out["no_all"].append(mod)
        out["all"][mod] = names or []
        if path.name == "__init__.py":
            out["faces" if mod == root.name else "indexes"][mod] = names or []
        elif not path.name.startswith("_"):
            out["public"] += [
                (mod, n.name)
                for n in tree.body
                if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
                and not n.name.startswith("_")
            ]
    return out


def _callers(project: Path) -> list[tuple[str, str]]:
    """``[(where, source)]`` of the code outside ``vpr_core`` that must use its face:
    ``vpr_study``, the notebooks and the starter (code cells), README and docs code blocks
    (tests and benchmarks may import modules)."""
    found = [
        (str(p.relative_to(project)), p.read_text(encoding="utf-8"))
        for pattern in ("vpr_study/**/*.py", "notebooks/scripts/*.py")
        for p in sorted(project.glob(pattern))
    ]
    for nb in [*sorted(project.glob("notebooks/*.ipynb")), project / "vpr_study/starter.ipynb"]:
        cells = json.loads(nb.read_text(encoding="utf-8"))["cells"]
        found += [
            (str(nb.relative_to(project)), "".join(c["source"]))
            for c in cells
            if c["cell_type"] == "code"
        ]
    for md in [project / "README.md", *sorted((project / "docs").glob("*.md"))]:
        text = md.read_text(encoding="utf-8")
        found += [
            (str(md.relative_to(project)), b)
            for b in re.findall(r"```python\n(.*?)```", text, re.S)
        ]
    return found


#: The faces of the workbench that the notebooks, the starter and README / docs code use.
STUDY_FACES = ("vpr_study", "vpr_study.viz")


def _imported(source: str) -> list[tuple[str, str]]:
    """``[(module, name)]`` of every absolute import in ``source`` (``name`` "" for ``import``)."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return []
    out: list[tuple[str, str]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level == 0:
            out += [(node.module or "", a.name) for a in node.names]
        elif isinstance(node, ast.Import):
            out += [(a.name, "") for a in node.names]
    return out


def reach_past(root: Path) -> list[str]:
    """Imports past a face by the code outside the package (:func:`_callers`): a ``root``
    module other than ``root`` itself, and (outside ``vpr_study``) a ``vpr_study`` module other
    than :data:`STUDY_FACES`: ``["where: module", ...]``; target none."""
    bad = []
    for where, source in _callers(root.parent):
        inside = where.startswith("vpr_study/")
        for m, _ in _imported(source):
            top = m.split(".")[0]
            if (top == root.name and m != root.name) or (
                top == "vpr_study" and not inside and m not in STUDY_FACES
            ):
                bad.append(f"{where}: {m}")
    return bad


def core_names_used(root: Path, caller: str = "vpr_study") -> dict[str, list[str]]:
    """``{name: [modules]}``: the distinct names of ``root`` that the package ``caller`` imports
    (a namespace module such as ``checks`` counts as one name)."""
    used: dict[str, list[str]] = defaultdict(list)
    for path in sorted((root.parent / caller).rglob("*.py")):
        for m, name in _imported(path.read_text(encoding="utf-8")):
            if m.split(".")[0] == root.name:
                used[f"{m}.{name}" if name else m].append(str(path.relative_to(root.parent)))
    return dict(used)


def _message(node: ast.expr | None) -> str | None:
    """The text of a raised exception's first argument, placeholders as ``{}``."""
    if isinstance(node, ast.Call):
        return _message(node.args[0]) if node.args else None
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in node.values)
    if isinstance(node, ast.BinOp):
        return (_message(node.left) or "{}") + (_message(node.right) or "{}")
    return None


def rule_sites(root: Path) -> dict[str, list[str]]:
    """``{message: ["file:line", ...]}`` over every ``raise`` with a message in ``root``."""
    sites: dict[str, list[str]] = defaultdict(list)
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Raise):
                text = _message(node.exc)
                if text:
                    where = f"{path.relative_to(root)}:{node.lineno}"
                    sites[" ".join(text.split())].append(where)
    return dict(sites)


_STOP = {"the", "and", "must", "got", "not", "with", "for", "its", "from", "this", "that", "are"}


def near_duplicates(sites: dict[str, list[str]], share: float = 0.6) -> list[list[str]]:
    """Groups of different messages sharing at least ``share`` of their words (for reading)."""
    words = {
        m: {w for w in re.findall(r"[a-z][a-z0-9_]+", m.lower()) if len(w) > 2} - _STOP
        for m in sites
    }
    keys = list(sites)
    parent = {k: k for k in keys}

    def top(k: str) -> str:
        while parent[k] != k:
            k = parent[k]
        return k

    for i, a in enumerate(keys):
        for b in keys[i + 1 :]:
            wa, wb = words[a], words[b]
            if wa and wb and len(wa & wb) / len(wa | wb) >= share:
                parent[top(a)] = top(b)
    groups: dict[str, list[str]] = defaultdict(list)
    for k in keys:
        groups[top(k)].append(k)
    return [g for g in groups.values() if len(g) > 1]


def _face_modules(root: Path) -> dict[str, tuple[str, ...]]:
    """The face's table of the modules whose names it holds (``_MODULES`` of ``__init__.py``)."""
    tree = ast.parse((root / "__init__.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.AnnAssign) and getattr(node.target, "id", "") == "_MODULES":
            return ast.literal_eval(node.value)
    return {}


def names_markdown(root: Path) -> str:
    """The face (``__init__.py``'s ``__all__``), one markdown row per module its names come
    from, and their total."""
    rows = ["| from | names |", "|---|---|"]
    for mod, names in _face_modules(root).items():
        where = f"`{root.name}.{mod}`" if mod else "modules handed out"
        rows.append(f"| {where} | {', '.join(f'`{n}`' for n in names)} |")
    total = len(face(root)["faces"].get(root.name, []))
    return "\n".join(rows) + f"\n\n{total} names in `{root.name}.__all__` (with `__version__`)."


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", default=str(Path(__file__).resolve().parents[1] / "vpr_core"))
    parser.add_argument("--files", action="store_true", help="one row per file")
    parser.add_argument("--rules", action="store_true", help="list rules raised from > 1 site")
    parser.add_argument("--names", action="store_true", help="public names per module")
    args = parser.parse_args()
    root = Path(args.root)
    if args.names:
        print(names_markdown(root))
        return
    groups: dict[str, Counter] = {}
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root)
        key = str(rel) if args.files else (rel.parts[0] if len(rel.parts) > 1 else "(top level)")
        groups.setdefault(key, Counter()).update(line_kinds(path.read_text(encoding="utf-8")))
    total: Counter = sum(groups.values(), Counter())
    width = max(len(k) for k in [*groups, "total"])
    print(f"{'':{width}}  {'lines':>6}  " + "  ".join(f"{k:>9}" for k in (*KINDS, GUARD)))
    for key, c in sorted(groups.items(), key=lambda kv: -kv[1].total()) + [("total", total)]:
        lines = sum(c[k] for k in KINDS)
        print(f"{key:{width}}  {lines:6d}  " + "  ".join(f"{c[k]:9d}" for k in (*KINDS, GUARD)))
    n = sum(total[k] for k in KINDS)
    print("share: " + ", ".join(f"{k} {total[k] / n:.0%}" for k in KINDS))
    print(f"guard lines / code lines: {total[GUARD] / max(total['code'], 1):.1%}")
    wide, options = signatures(root)
    print(f"functions with more than {MAX_PARAMETERS} parameters: {len(wide)}")
    for n_params, where in wide:
        print(f"  {n_params:3d}  {where}")
    print("signatures per option: " + ", ".join(f"{o} {options[o]}" for o in OPTIONS))
    f = face(root)
    print(f"the face ({root.name}.__all__): {len(f['faces'].get(root.name, []))} names")
    sizes = {mod: len(names) for mod, names in f["indexes"].items()}
    print(
        "stage indexes (subpackage __all__, for the package, tests, benchmarks): "
        + ", ".join(f"{m} {n}" for m, n in sizes.items())
    )
    if root.name == "vpr_core":
        print(f"distinct {root.name} names vpr_study imports: {len(core_names_used(root))}")
    print(f"imports by callers past a face: {len(reach_past(root))} (target 0)")
    print(f"public functions and classes inside the package (behind its faces): {len(f['public'])}")
    print(f"modules without __all__: {len(f['no_all'])}")
    sites = rule_sites(root)
    repeated = {m: w for m, w in sites.items() if len(w) > 1}
    near = near_duplicates(sites)
    print(f"raise sites: {sum(map(len, sites.values()))}, rules (distinct messages): {len(sites)}")
    print(f"rules raised from more than one site: {len(repeated)} (target 0)")
    print(f"groups of near-duplicate messages (60% shared words; read them): {len(near)}")
    if args.rules:
        for message, where in sorted(repeated.items()):
            print(f"  {len(where)}x {message[:90]!r}: {', '.join(where)}")
        for group in near:
            print("  near: " + " | ".join(f"{m[:60]!r} {sites[m]}" for m in group))
        for where in reach_past(root):
            print(f"  past a face: {where}")
        for mod in f["no_all"]:
            print(f"  no __all__: {mod}")


if __name__ == "__main__":
    main()
