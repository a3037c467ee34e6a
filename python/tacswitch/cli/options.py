"""Option checks shared by the commands: usage errors, output paths, models, extraction options.

A value an option names that cannot be used (a missing ``--centres`` file, an ``-o`` path under
a file, an image given as ``--model``) is a :class:`UsageError`: one line naming the option,
exit code 2 (as argparse's own usage errors). Problems with the inputs' contents stay
``ValueError`` (exit code 1).
"""

from __future__ import annotations

import argparse
import errno
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")


class UsageError(ValueError):
    """An option's value cannot be used; the message starts with the option's name."""


def _blocking_file(path: Path) -> Path | None:
    """The nearest existing ancestor of ``path`` that is not a folder (what stops a mkdir)."""
    for parent in path.parents:
        if parent.exists():
            return None if parent.is_dir() else parent
    return None


def _os_reason(exc: OSError) -> str:
    """An OS error as words, without the raw ``[Errno N]`` prefix."""
    if exc.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if exc.errno == errno.EROFS:
        return "read-only file system"
    if exc.errno == errno.ENOSPC:
        return "no space left on the device"
    return (exc.strerror or type(exc).__name__).lower()


def _make_dir(folder: Path, option: str, what: str) -> None:
    """Creates ``folder`` (and its parents); :class:`UsageError` ``"{option}: {what}: why"``."""
    blocker = _blocking_file(folder / "x")
    if blocker is not None:
        raise UsageError(f"{option}: {what}: {str(blocker)!r} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"{option}: {what}: {_os_reason(exc)}") from None


def output_dir(path: str | os.PathLike[str], option: str) -> Path:
    """The output folder ``path``, created if missing; :class:`UsageError` naming ``option``
    if it is a file or cannot be created (a file on the way, no permission)."""
    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"{option}: {str(folder)!r} is a file; give a folder")
    _make_dir(folder, option, f"cannot create folder {str(folder)!r}")
    _check_writable(folder, option)
    return folder


def output_file(path: str | os.PathLike[str], option: str) -> Path:
    """The output file ``path``, its parent folders created; :class:`UsageError` naming
    ``option`` if it is a folder or its folder cannot be made or written."""
    target = Path(path)
    if target.is_dir():
        raise UsageError(f"{option}: {str(target)!r} is a folder; give a file name")
    parent = target.parent
    _make_dir(parent, option, f"cannot write {str(target)!r}")
    _check_writable(parent, option)
    if target.exists() and not os.access(target, os.W_OK):
        raise UsageError(f"{option}: cannot overwrite {str(target)!r}: permission denied")
    return target


def csv_output(path: str | os.PathLike[str], option: str) -> Path:
    """:func:`output_file` for a CSV: the name must end in ``.csv``, so a typo such as
    ``-o frame.png`` never replaces an image (or anything else) with CSV text."""
    target = Path(path)
    if not target.is_dir() and target.suffix.lower() != ".csv":  # a folder: output_file says so
        raise UsageError(f"{option}: {str(path)!r} is not a .csv file name; this command "
                         "writes CSV")
    return output_file(path, option)


class StreamingCsv:
    """A CSV log written row by row (flushed, so it can be read while a camera runs) that is
    opened only at its first row: a source that fails before any frame (a typo in the name, a
    video that does not decode, a camera that is not there) leaves an existing file as it was.
    A run that fails later keeps the rows written so far. Use as a context manager."""

    def __init__(self, path: str | os.PathLike[str], header: list[str]) -> None:
        self.path = Path(path)
        self.header = header
        self._fh: Any = None
        self._writer: Any = None

    def __enter__(self) -> StreamingCsv:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def opened(self) -> bool:
        """Whether a row was written (the file then holds this run's log)."""
        return self._fh is not None

    def writerow(self, row: list[Any]) -> None:
        """Writes ``row`` (after the header, at the first one) and flushes."""
        import csv

        if self._fh is None:
            self._fh = open(self.path, "w", newline="")  # closed by close()
            self._writer = csv.writer(self._fh)
            self._writer.writerow(self.header)
        self._writer.writerow(row)
        self._fh.flush()

    def close(self) -> None:
        if self._fh is not None:
            self._fh.close()


def _check_writable(folder: Path, option: str) -> None:
    """:class:`UsageError` naming ``option`` unless a file can be created in ``folder``: a
    real try, since ``os.access`` passes root, read-only mounts and ``/proc`` alike."""
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UsageError(f"{option}: cannot write in {str(folder)!r}: permission denied")
    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        # An existing folder that refuses new files with "no such file" (/proc, /sys): say so.
        reason = ("the folder does not accept new files (a virtual or read-only file system?)"
                  if exc.errno == errno.ENOENT and folder.is_dir() else _os_reason(exc))
        raise UsageError(f"{option}: cannot write in {str(folder)!r}: {reason}") from None


def input_file(path: str | os.PathLike[str], option: str) -> Path:
    """``path`` if it is an existing file; :class:`UsageError` naming ``option`` otherwise."""
    p = Path(path)
    if p.is_dir():
        raise UsageError(f"{option}: {str(p)!r} is a folder; give a file")
    if not p.is_file():
        raise UsageError(f"{option}: no file at {str(p)!r}")
    if not os.access(p, os.R_OK):
        raise UsageError(f"{option}: cannot read {str(p)!r}: permission denied")
    return p


def preset_option(name: str, option: str = "--preset") -> str:
    """``name`` if it is a simulator preset; :class:`UsageError` naming ``option`` (and the
    presets) otherwise."""
    from tacswitch.sim.presets import PRESETS

    if name not in PRESETS:
        raise UsageError(f"{option}: unknown preset {name!r}; choose from "
                         f"{', '.join(sorted(PRESETS))}")
    return name


def load_model_option(loader: Callable[[Any], T], value: str | None,
                      option: str = "--model") -> T:
    """``loader(value)`` with the library's ``model: ...`` errors (missing file, not an ONNX
    model, a model of the wrong kind) turned into :class:`UsageError` naming ``option``."""
    try:
        return loader(value)
    except (ValueError, FileNotFoundError) as exc:
        text = str(exc)
        if text.startswith("model:"):
            raise UsageError(f"{option}:{text[len('model:'):]}") from None
        raise


def add_device_option(p: argparse.ArgumentParser, what: str) -> None:
    """Adds ``--device auto|cpu|cuda`` (default auto) to ``p``; ``what`` names what runs
    there (for the help). Check the value with :func:`device_option` before any work."""
    p.add_argument("--device", choices=("auto", "cpu", "cuda"), default="auto",
                   help=f"where {what} runs: auto (default: a CUDA GPU when onnxruntime offers "
                        "one, i.e. onnxruntime-gpu is installed and sees a GPU; else the CPU), "
                        "cpu, or cuda (an error when onnxruntime has no CUDA)")


def device_option(value: str, option: str = "--device") -> str:
    """``value`` if onnxruntime can run there (:func:`tacswitch._ort.providers`);
    :class:`UsageError` naming ``option`` otherwise (``cuda`` without CUDA)."""
    from tacswitch._ort import providers

    try:
        providers(value)
    except ValueError as exc:
        raise UsageError(f"{option}:{str(exc).removeprefix('device:')}") from None
    return value


# --- argparse value types: a bad value is argparse's own usage error (exit 2, naming the flag) --

def odd_size(text: str) -> int:
    """An odd whole number >= 3 (a box size, px)."""
    value = count(text)
    if value < 3 or value % 2 == 0:
        raise argparse.ArgumentTypeError(f"expected an odd number of pixels >= 3, got {text!r}")
    return value


def count(text: str) -> int:
    """A whole number >= 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return value


def positive_count(text: str) -> int:
    """A whole number in [1, MAX_COUNT]."""
    from tacswitch._checks import MAX_COUNT

    try:
        value = int(text)
    except ValueError:
        value = 0  # not a whole number: the same message as one out of range
    if not 1 <= value <= MAX_COUNT:
        raise argparse.ArgumentTypeError(f"expected a whole number in [1, {MAX_COUNT}], "
                                         f"got {text!r}")
    return value


def positive(text: str) -> float:
    """A finite number > 0 (NaN and infinity refused)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _or_auto(parse: Callable[[str], Any], expected: str) -> Callable[[str], Any]:
    """An argparse type: ``'auto'`` as it is, anything else through ``parse`` (its refusal
    reworded to say that ``'auto'`` was possible too)."""
    def parse_or_auto(text: str) -> Any:
        if text == "auto":
            return text
        try:
            return parse(text)
        except argparse.ArgumentTypeError:
            raise argparse.ArgumentTypeError(f"expected {expected} or 'auto', "
                                             f"got {text!r}") from None
    return parse_or_auto


#: Pixels > 0 (finite) or ``'auto'``.
px_or_auto = _or_auto(positive, "pixels > 0")
#: A whole number >= 0 or ``'auto'`` (``--dilate``).
_dilate = _or_auto(count, "a whole number >= 0")


def fraction(text: str) -> float:
    value = positive(text)
    if value > 1:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1], got {text!r}")
    return value


def ratio(text: str) -> float:
    """A finite ratio >= 1 (an aspect ratio)."""
    value = positive(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a ratio >= 1, got {text!r}")
    return value


def bounded(low: float, high: float) -> Callable[[str], float]:
    """An argparse type: a number in ``(low, high]`` (finite; NaN refused)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not low < value <= high:
            raise argparse.ArgumentTypeError(f"expected a number in ({low:g}, {high:g}], "
                                             f"got {text!r}")
        return value

    return parse


# --- marker extraction options (tacswitch.extract_markers keyword arguments) -----------------


#: (flag, extract_markers keyword, argparse keywords) of each extraction option.
EXTRACTION_OPTIONS: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("--polarity", "polarity", {"choices": ("dark", "bright"),
                                "help": "markers darker (painted dots, default) or brighter "
                                        "(pins) than the gel"}),
    ("--threshold", "threshold", {"type": positive, "metavar": "GREY",
                                  "help": "marker contrast threshold in grey levels (default: "
                                          "chosen per image)"}),
    ("--block-size", "block_size", {"type": odd_size, "metavar": "PX",
                                    "help": "odd box size for the local background, px "
                                            "(default: max(15, min(H, W) // 8))"}),
    ("--min-area", "min_area", {"type": count, "metavar": "PX",
                                "help": "smallest marker, px (default: max(4, 5e-5 * H * W), "
                                        "at most a quarter of the typical marker's area)"}),
    ("--max-area", "max_area", {"type": count, "metavar": "PX",
                                "help": "largest marker, px (default: 0.02 * H * W)"}),
    ("--min-fill", "min_fill", {"type": fraction, "metavar": "F",
                                "help": "smallest area / bounding-box area (default: 0.35; "
                                        "a disc has 0.785)"}),
    ("--max-aspect", "max_aspect", {"type": ratio, "metavar": "R",
                                    "help": "largest bounding-box aspect ratio (default: 3)"}),
)


def add_extraction_options(p: argparse.ArgumentParser, *, border_default: str,
                           dilate: bool) -> None:
    """Adds :data:`EXTRACTION_OPTIONS`, ``--exclude-border/--keep-border`` (the default named
    by ``border_default``) and, if ``dilate``, ``--dilate`` to ``p`` in their own group; every
    default is None, so :func:`extraction_options` passes only what the user set."""
    group = p.add_argument_group(
        "marker extraction", "options of tacswitch.extract_markers; unset options keep the "
        "library's defaults (chosen per image)")
    for flag, dest, kw in EXTRACTION_OPTIONS:
        group.add_argument(flag, dest=f"x_{dest}", default=None, **kw)
    if dilate:
        group.add_argument("--dilate", dest="x_dilate", type=_dilate, default=None,
                           metavar="N|auto",
                           help="grow the marker mask before filling: N 3x3-cross dilations, "
                                "or 'auto' (per marker, until the ring around it matches the "
                                "local background: soft edges and codec rings inside); "
                                "default: the library's")
    border = group.add_mutually_exclusive_group()
    border.add_argument("--exclude-border", dest="x_exclude_border", action="store_const",
                        const=True, default=None,
                        help="drop markers cut by the frame edge"
                             + (" (default)" if border_default == "exclude" else ""))
    border.add_argument("--keep-border", dest="x_exclude_border", action="store_const",
                        const=False,
                        help="keep markers cut by the frame edge"
                             + (" (default)" if border_default == "keep" else ""))


def extraction_options(args: argparse.Namespace) -> dict[str, Any]:
    """The extraction keyword arguments the user set (``x_*`` attributes that are not None),
    checked before any input is read: :class:`UsageError` naming the flag for a value the
    library refuses (a threshold above 255, an even or huge block size, min above max area)."""
    import numpy as np

    from tacswitch.markers import extract_markers

    opts = {k[2:]: v for k, v in vars(args).items() if k.startswith("x_") and v is not None}
    try:
        # A tiny blank frame: extraction checks every option (the ranges do not depend on the
        # image), and it costs microseconds.
        extract_markers(np.zeros((16, 16, 3), np.uint8), **opts)
    except (TypeError, ValueError) as exc:
        name, _, reason = str(exc).partition(": ")
        raise UsageError(f"--{name.replace('_', '-')}: {reason}") from None
    return opts
