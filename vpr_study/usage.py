"""The ``vpr-study`` entry point: its top-level help and ``--version`` from the standard library
alone, each command's ``--help`` without torch (answered at once), every command through
:mod:`vpr_study.cli`."""

from __future__ import annotations

import argparse
import sys

__all__ = ["COMMANDS", "DESCRIPTION", "main", "top_parser", "version_text"]

DESCRIPTION = """vpr-study eval: methods on a dataset; run: the study; findings: claims vs results.

Examples::

    vpr-study eval --dataset synthetic --method dense   # writes under user/
    vpr-study eval --dataset gardens_point --root ~/data/gardens_point --method classical
    vpr-study eval --dataset nordland --root ../shared/data/nordland_64x32 --method dense \\
        --pooling roi --shortlist 25             # all 3,576 x 3,576 places
    vpr-study run --dataset synthetic            # all notebooks, figures/ and results/
    vpr-study run --dataset synthetic --quick    # the small headless run used by the tests
"""

#: Each command and its one-line help (the full parser, :func:`vpr_study.arguments.parser`,
#: uses the same words; ``vpr-study COMMAND --help`` lists its options).
COMMANDS = {
    "eval": "evaluate one or more methods on a dataset",
    "run": "execute the study notebooks and regenerate figures/",
    "findings": "the paper's claims vs results/<dataset>/ (Markdown)",
}


def version_text() -> str:
    """``vpr-study <version>`` of the installed package (``--version``)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return f"vpr-study {version('vpr-landmarks')}"
    except PackageNotFoundError:  # pragma: no cover - a bare source tree
        return "vpr-study (not installed)"


def top_parser() -> argparse.ArgumentParser:
    """The top level of the ``vpr-study`` parser: its description, ``--version`` and commands."""
    p = argparse.ArgumentParser(
        prog="vpr-study",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=version_text())
    sub = p.add_subparsers(dest="command", required=True)
    for name, text in COMMANDS.items():
        sub.add_parser(name, help=text)
    return p


def _asks_help(args: list[str]) -> bool:
    """Whether ``args`` is a command asking for its help (``eval --method dense -h``)."""
    own = args[1 : args.index("--")] if "--" in args else args[1:]
    return args[0] in COMMANDS and any(a in ("-h", "--help") for a in own)


def main(argv: list[str] | None = None) -> int:
    """``vpr-study``: ``--help``, ``--version`` (or no command) answered here, a command's
    ``--help`` by the full parser without the pipeline, everything else by the CLI."""
    args = sys.argv[1:] if argv is None else list(argv)
    if not args or args[0] in ("-h", "--help", "--version"):
        top_parser().parse_args(args)  # prints the help (or the usage error) and exits
    if _asks_help(args):  # the full parser, built from names alone (vpr_study.choices)
        from vpr_study.arguments import parser

        parser(dict.fromkeys(COMMANDS, lambda _: 0)).parse_args(args)  # prints it and exits
    from vpr_study.cli import main as cli_main  # the pipeline (and torch) only for a command

    return cli_main(args)
