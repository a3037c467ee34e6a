"""The ``tacswitch`` command line: one entry point, one sub-command per capability."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

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


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser (one sub-parser per command)."""
    from tacswitch import __version__

    parser = argparse.ArgumentParser(
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
    """Runs the CLI. User mistakes print one line on stderr and return 1, never a traceback."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.run(args) or EXIT_OK)
    except (ValueError, TypeError, FileNotFoundError, NotADirectoryError) as exc:
        print(f"tacswitch {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print(f"tacswitch {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
