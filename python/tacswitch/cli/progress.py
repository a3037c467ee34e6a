"""Progress bars for the commands (tqdm), in one place.

Bars go to **stderr**, so stdout (CSV, paths, summaries that scripts parse) is never touched.
A bar appears only once its work has run for :data:`DELAY_S` seconds (short jobs print nothing),
and ``-q/--quiet`` disables it. Lines printed while a bar is live go through :func:`say`, which
lifts the bar out of the way first.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import Any

#: Seconds a job runs before its bar is drawn (the issue: bars on anything longer than a second).
DELAY_S = 1.0
#: Seconds between redraws on a terminal; a log file (stderr not a terminal) gets fewer lines.
REDRAW_TTY_S, REDRAW_FILE_S = 0.1, 5.0


def progress(iterable: Iterable[Any] | None = None, *, total: int | None = None,
             desc: str | None = None, unit: str = "it", quiet: bool = False) -> Any:
    """A tqdm bar on stderr (``quiet``: a disabled one that still iterates and counts).

    Use it as tqdm: wrap an iterable, or call ``.update(n)``; close it (or use ``with``) at
    the end. ``total=None`` (a camera, a video without a frame count) shows a count and a rate.
    """
    from tqdm import tqdm

    stream = sys.stderr
    tty = bool(getattr(stream, "isatty", lambda: False)())
    return tqdm(iterable, total=total, desc=desc, unit=unit, file=stream, disable=quiet,
                delay=DELAY_S, mininterval=REDRAW_TTY_S if tty else REDRAW_FILE_S,
                dynamic_ncols=tty, leave=True)


def say(message: str, *, quiet: bool = False) -> None:
    """Prints ``message`` on stdout without garbling a live bar (nothing when ``quiet``)."""
    if quiet:
        return
    from tqdm import tqdm

    tqdm.write(message, file=sys.stdout)
