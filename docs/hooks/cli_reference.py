"""MkDocs hook: the command-line reference, generated from the `ehm` command itself.

A page that holds the line `<!-- ehm commands -->` gets, in its place, one section per command
in the order `ehm --help` lists them: its help, its usage, and a table of its arguments and
options as `ehm COMMAND --help` describes them.
"""

from __future__ import annotations

import re
from typing import Any

import typer

MARKER = "<!-- ehm commands -->"


def on_page_markdown(markdown: str, **_: Any) -> str:
    if MARKER not in markdown:
        return markdown
    return markdown.replace(MARKER, commands_markdown())


def commands_markdown() -> str:
    """Markdown for every command of `ehm`."""
    from ehm.cli import app

    group = typer.main.get_command(app)
    root = typer.Context(group, info_name="ehm")
    sections = []
    for name in group.list_commands(root):
        command = group.commands[name]
        context = typer.Context(command, info_name=name, parent=root)
        usage = re.sub(
            r"\{(\w+)\}",
            lambda m: m.group(1).upper(),
            " ".join(command.collect_usage_pieces(context)),
        )
        rows = [_row(param, context) for param in command.params if not param.hidden]
        sections.append(
            "\n".join(
                [
                    f"## ehm {name}",
                    "",
                    _paragraphs(command.help or ""),
                    "",
                    f"```\nehm {name} {usage}\n```",
                    "",
                    "| argument or option | meaning |",
                    "| --- | --- |",
                    *rows,
                ]
            )
        )
    return "\n\n".join(sections)


def _row(param: Any, context: typer.Context) -> str:
    """One table row: the argument's name, or the option's flags and value; its help."""
    if param.param_type_name == "argument":
        name = param.name.upper() + ("..." if param.nargs == -1 else "")
        flags, help_text = name, param.help or ""
    else:
        flags, help_text = param.get_help_record(context)
    return f"| `{flags}` | {_cell(help_text)} |"


def _paragraphs(text: str) -> str:
    """A command's help as Markdown: its lines joined, blank lines kept between paragraphs."""
    return "\n\n".join(" ".join(part.split()) for part in text.split("\n\n"))


def _cell(text: str) -> str:
    """Text that is safe inside a Markdown table cell."""
    return " ".join(text.split()).replace("|", "\\|")
