"""Size of ``vpr_core`` by kind of line: code, docstring, comment, blank, per package.

Issue 16 measures the package with ``find vpr_core -name '*.py' | xargs wc -l``; this script
prints the same total and splits it, so a reader sees what the lines are: statements, the
docstrings the project keeps on every public function (Google style, with shapes), comments and
blank lines. Docstring lines are the lines of a module, class or function docstring.

Issue 31 adds the guard share: guard lines (``raise`` statements, and the test of an ``if``
whose only body is a ``raise``) over code lines; the anchors (hloc, LightGlue, kornia) are 1-7%.
It also counts how values flow (DESIGN.md habit 5): the functions with more than 8 explicit
parameters, and in how many signatures each option the issue names appears (target: 3).

Usage::

    .venv/bin/python benchmarks/code_size.py            # per package, then the total
    .venv/bin/python benchmarks/code_size.py --files    # per file
    .venv/bin/python benchmarks/code_size.py --root vpr_study   # the study's tooling
"""

from __future__ import annotations

import argparse
import ast
from collections import Counter
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", default=str(Path(__file__).resolve().parents[1] / "vpr_core"))
    parser.add_argument("--files", action="store_true", help="one row per file")
    args = parser.parse_args()
    root = Path(args.root)
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


if __name__ == "__main__":
    main()
