"""Every option of ``tacswitch`` and of each (sub-)command has a help string (issue 32)."""

from __future__ import annotations

import argparse
from collections.abc import Iterator

from tacswitch.cli import build_parser


def _parsers(parser: argparse.ArgumentParser, path: str = "tacswitch"
             ) -> Iterator[tuple[str, argparse.ArgumentParser]]:
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, f"{path} {name}")


def test_every_option_has_help() -> None:
    missing = []
    for path, parser in _parsers(build_parser()):
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            if not action.help or action.help == argparse.SUPPRESS:
                name = "/".join(action.option_strings) or action.dest
                missing.append(f"{path}: {name}")
    assert not missing, "options without help:\n" + "\n".join(missing)


def test_every_command_help_renders() -> None:
    for path, parser in _parsers(build_parser()):
        assert parser.format_help().strip(), path
