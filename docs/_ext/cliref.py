"""Generate ``reference/cli.md``, the command-line reference, from the ``workbench`` parser.

Each subcommand's usage, description and arguments come from
:func:`workbench.experiment.cli.parser.build_parser` when the documentation is built, so a
new option or a changed help text shows up in the page without an edit.
"""

from __future__ import annotations

import argparse
from typing import Any


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:  # argparse keeps its subcommands here only
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _helps(parser: argparse.ArgumentParser) -> dict[str, str]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return {a.dest: a.help or "" for a in action._choices_actions}
    return {}


def _argument(action: argparse.Action) -> str:
    name = ", ".join(action.option_strings) or (action.metavar or action.dest)
    if action.option_strings and action.nargs != 0:
        metavar = action.metavar or action.dest.upper()
        name += f" {' '.join(metavar) if isinstance(metavar, tuple) else metavar}"
    return name


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def render() -> str:
    """The page: per subcommand its usage and a table of its arguments."""
    from workbench.experiment.cli.parser import build_parser

    parser = build_parser()
    helps = _helps(parser)
    lines = ["# Command-line reference", "",
             "The `workbench` command, generated from its argparse parser "
             "(`workbench.experiment.cli.parser.build_parser`) when the documentation is "
             "built. `workbench COMMAND --help` prints the same.", "",
             "```text", parser.format_usage().strip(), "```", ""]
    for name, sub in _subparsers(parser).items():
        help_text = _cell(helps.get(name, ""))
        lines += [f"## `workbench {name}`", "", help_text[:1].upper() + help_text[1:]
                  + ("." if helps.get(name) else ""), ""]
        if sub.description:
            lines += [_cell(sub.description), ""]
        lines += ["```text", " ".join(sub.format_usage().split()), "```", "",
                  "| argument | default | help |", "|---|---|---|"]
        for action in sub._actions:
            if isinstance(action, argparse._HelpAction) or action.help == argparse.SUPPRESS:
                continue
            shown = ("" if action.default in (None, False, argparse.SUPPRESS)
                     or action.nargs == 0 else f"`{action.default}`")
            lines.append(f"| `{_cell(_argument(action))}` | {shown} | "
                         f"{_cell(action.help or '')} |")
        lines.append("")
    return "\n".join(lines)


def setup(app: Any) -> dict[str, Any]:
    """Register the page's generation at the start of every build."""
    from generated_page import connect  # docs/_ext, on the path conf.py sets

    return connect(app, "cli.md", render)
