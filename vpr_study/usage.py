"""The ``vpr-study`` entry point: its top-level help from the standard library alone (no torch,
answered at once), every command through :mod:`vpr_study.cli`."""

from __future__ import annotations

import argparse
import sys

__all__ = ["COMMANDS", "DESCRIPTION", "main", "top_parser"]

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


def top_parser() -> argparse.ArgumentParser:
    """The top level of the ``vpr-study`` parser: its description and commands."""
    p = argparse.ArgumentParser(
        prog="vpr-study",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = p.add_subparsers(dest="command", required=True)
    for name, text in COMMANDS.items():
        sub.add_parser(name, help=text)
    return p


def main(argv: list[str] | None = None) -> int:
    """``vpr-study``: ``--help`` (or no command) answered here, everything else by the CLI."""
    args = sys.argv[1:] if argv is None else list(argv)
    if not args or args[0] in ("-h", "--help"):
        top_parser().parse_args(args)  # prints the help (or the usage error) and exits
    from vpr_study.cli import main as cli_main  # the pipeline (and torch) only for a command

    return cli_main(args)
