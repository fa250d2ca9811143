"""Every flag the README and docs/service.md document is one ``--help`` shows, and the
README's command reference lists every flag of every command (no more, no fewer)."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from service.cli.main import build_parser

ROOT = Path(__file__).resolve().parents[1]
FLAG = re.compile(r"(?<![\w-])(--[a-z][a-z0-9-]*|-[a-zA-Z])(?![\w-])")


def help_flags() -> dict[str, set[str]]:
    """Option strings of ``railtwin`` ("") and of each command, as ``--help`` shows them; a
    command group's commands (``railtwin fleet serve``) under ``"fleet serve"``, the group
    itself not (it has no flags of its own)."""
    found: dict[str, set[str]] = {}
    _collect(build_parser(), "", found)
    return found


def _collect(parser: argparse.ArgumentParser, name: str, found: dict[str, set[str]]) -> None:
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if name == "" or not subs:
        found[name] = _shown(parser)
    for action in subs:
        for sub_name, sub in action.choices.items():
            _collect(sub, f"{name} {sub_name}".strip(), found)


def _groups() -> set[str]:
    """Commands that are groups of commands (``fleet``)."""
    return {name.split()[0] for name in help_flags() if " " in name}


def _shown(parser: argparse.ArgumentParser) -> set[str]:
    return {s for a in parser._actions if a.help != argparse.SUPPRESS for s in a.option_strings} - {
        "-h",
        "--help",
    }


def documented(path: Path) -> dict[str, set[str]]:
    """Flags of the ``railtwin ...`` usage lines in the code blocks of ``path``, by command
    (a line indented under one continues it)."""
    found: dict[str, set[str]] = {}
    groups = _groups()
    in_code, command = False, None
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            in_code, command = not in_code, None
            continue
        if not in_code:
            continue
        m = re.match(r"(?:\$ )?railtwin(?: \[[^]]*\])*\s+([a-z][a-z-]*)", line)
        if line.startswith(("railtwin ", "$ railtwin ")):
            words = line.split()
            command = "" if (m is None or words[1].startswith("[")) else m.group(1)
            if command in groups and len(words) > 2:
                command = f"{command} {words[2]}"
            text = line
        elif command is not None and line.startswith(" "):
            text = line
        else:
            command = None
            continue
        text = text.split("#", 1)[0]  # a comment is not usage
        if command == "":  # ``railtwin [--debug] [--version] COMMAND``
            text = text.split("COMMAND", 1)[0]
        found.setdefault(command, set()).update(FLAG.findall(text))
    return found


def test_the_readme_lists_every_flag_of_every_command() -> None:
    shown = help_flags()
    doc = documented(ROOT / "README.md")
    assert set(doc) >= set(shown), f"commands without a usage line: {set(shown) - set(doc)}"
    for command, flags in shown.items():
        assert doc[command] == flags, (
            f"railtwin {command}: documented but not in --help: {doc[command] - flags}; "
            f"in --help but not documented: {flags - doc[command]}"
        )


@pytest.mark.parametrize(
    "path", ["docs/service.md", "deploy/zenoh/README.md", "recordings/samples/README.md"]
)
def test_other_docs_document_only_real_flags(path: str) -> None:
    shown = help_flags()
    for command, flags in documented(ROOT / path).items():
        assert command in shown, f"{path}: no command railtwin {command}"
        assert flags <= shown[command], (
            f"{path}: railtwin {command}: not in --help: {flags - shown[command]}"
        )


def test_the_parser_of_usage_lines_finds_flags() -> None:
    assert FLAG.findall("[--state DIR | --no-state] [-o RESULT.json] --site S") == [
        "--state",
        "--no-state",
        "-o",
        "--site",
    ]
