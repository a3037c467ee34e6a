"""The ``tacswitch`` command line: one entry point, one sub-command per capability."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import NoReturn

from tacswitch.cli import (
    bench,
    demo,
    evaluate,
    export,
    finetune,
    markers,
    motion,
    remove_markers,
    simulate,
    slip,
    track,
    train,
)

COMMANDS = {
    "demo": demo,
    "markers": markers,
    "track": track,
    "slip": slip,
    "remove-markers": remove_markers,
    "simulate": simulate,
    "bench": bench,
    "motion": motion,
    "train": train,
    "finetune": finetune,
    "evaluate": evaluate,
    "export": export,
}

#: Exit codes scripts can rely on.
EXIT_OK, EXIT_ERROR, EXIT_USAGE = 0, 1, 2


class _OneLineErrors(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on stderr, ``PROG: error: MESSAGE``
    and where to read the usage, as every other error of the command line (argparse would print
    its whole usage block above it); exit status 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (usage: {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (one sub-parser per command)."""
    from tacswitch import __version__

    parser = _OneLineErrors(
        prog="tacswitch",
        description="Mode-switchable optical tactile sensing: markers, tracking, slip, "
        "marker removal, marker motion from markerless images.",
    )
    parser.add_argument("--version", action="version", version=f"tacswitch {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in COMMANDS.values():
        module.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Runs the CLI. User mistakes print one line on stderr, never a traceback: exit code 2 for
    an option whose value cannot be used (as argparse's usage errors: a wrong ``--model``, an
    output path under a file, a missing ``--centres`` file), 1 for inputs that cannot be
    processed."""
    from tacswitch.cli.options import UsageError
    from tacswitch.cli.sources import quiet_opencv

    parser = build_parser()
    args = parser.parse_args(argv)
    quiet_opencv()
    try:
        return int(args.run(args) or EXIT_OK)
    except UsageError as exc:
        print(f"tacswitch {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except (ValueError, TypeError, OSError) as exc:
        message = _as_option(_one_line(exc), _option_strings(parser, args.command))
        print(f"tacswitch {args.command}: error: {message}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print(f"tacswitch {args.command}: interrupted", file=sys.stderr)
        return 130


def _option_strings(parser: argparse.ArgumentParser, command: str) -> set[str]:
    """Every option string of ``command`` and of its own subcommands (``evaluate slip``)."""
    found: set[str] = set()
    todo = [a.choices[command] for a in parser._actions  # argparse keeps no public handle
            if isinstance(a, argparse._SubParsersAction) and command in a.choices]
    while todo:
        sub = todo.pop()
        for action in sub._actions:
            found.update(action.option_strings)
            if isinstance(action, argparse._SubParsersAction):
                todo.extend(action.choices.values())
    return found


def _as_option(message: str, options: set[str]) -> str:
    """A library error naming a Python argument (``dilate: ...``, ``ref: ...``) as the
    command's option that passed it (``--dilate: ...``), when the command has that option."""
    name, sep, rest = message.partition(":")
    flag = "--" + name.replace("_", "-")
    return f"{flag}:{rest}" if sep and name.isidentifier() and flag in options else message


def _one_line(exc: BaseException) -> str:
    """An error as one line; an OS error raised by the system (a disk full, a permission lost
    mid-run) as words and the file, without the raw ``[Errno N]`` prefix."""
    if isinstance(exc, OSError) and exc.errno is not None and exc.strerror:
        where = f": {str(exc.filename)!r}" if exc.filename else ""
        return f"{exc.strerror.lower()}{where}"
    text = str(exc).strip() or type(exc).__name__
    return " ".join(text.split())


if __name__ == "__main__":
    sys.exit(main())
