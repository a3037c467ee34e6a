"""Progress bars and messages of the commands (tqdm), in one place.

Bars go to **stderr**, and only when stderr is a terminal: a log file or a pipe gets no bar
(the commands print their own summary on stdout). A bar appears only once its work has run for
:data:`DELAY_S` seconds (short jobs print nothing), and ``-q/--quiet`` disables it. Lines
printed while a bar is live go through :func:`say` (stdout) or :func:`warn` (stderr), which
lift the bar out of the way first.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import Any

#: Seconds a job runs before its bar is drawn (the issue: bars on anything longer than a second).
DELAY_S = 1.0
#: Seconds between redraws.
REDRAW_S = 0.1


def stderr_is_terminal() -> bool:
    """Whether stderr is an interactive terminal (the only place a bar is drawn)."""
    return bool(getattr(sys.stderr, "isatty", lambda: False)())


def progress(iterable: Iterable[Any] | None = None, *, total: int | None = None,
             desc: str | None = None, unit: str = "it", quiet: bool = False) -> Any:
    """A tqdm bar on stderr; a disabled one that still iterates and counts when ``quiet`` or
    when stderr is not a terminal.

    Use it as tqdm: wrap an iterable, or call ``.update(n)``; close it (or use ``with``) at
    the end. ``total=None`` (a camera, a video without a frame count) shows a count and a rate.
    """
    from tqdm import tqdm

    return tqdm(iterable, total=total, desc=desc, unit=unit, file=sys.stderr,
                disable=quiet or not stderr_is_terminal(), delay=DELAY_S,
                mininterval=REDRAW_S, dynamic_ncols=True, leave=True)


def _bar_on_screen() -> bool:
    """Whether a bar has been drawn and is still live (``tqdm.write`` redraws every live bar
    after its line, even one still inside its delay: a 0.3 s job would show one)."""
    from tqdm import tqdm

    return any(not getattr(bar, "disable", True)
               and getattr(bar, "last_print_t", 0.0) >= bar.start_t + bar.delay
               for bar in list(getattr(tqdm, "_instances", ())))


def _write(message: str, stream: Any) -> None:
    if _bar_on_screen():
        from tqdm import tqdm

        tqdm.write(message, file=stream)
    else:
        print(message, file=stream, flush=True)


def say(message: str, *, quiet: bool = False) -> None:
    """Prints ``message`` on stdout without garbling a live bar (nothing when ``quiet``)."""
    if not quiet:
        _write(message, sys.stdout)


def warn(command: str, message: str) -> None:
    """Prints ``tacswitch COMMAND: warning: MESSAGE`` on stderr (also with ``-q``: a warning
    is about the result), without garbling a live bar."""
    _write(f"tacswitch {command}: warning: {message}", sys.stderr)
