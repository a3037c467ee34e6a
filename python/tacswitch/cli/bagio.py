"""ROS bag options shared by the streaming commands: ``BAG --topic /name`` as a source and
``--out-bag PATH`` for a new bag with the results (:mod:`tacswitch.bags`)."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from tacswitch.cli.options import UsageError

#: The bag options, as (flag, attribute).
FLAGS = (("--topic", "topic"), ("--out-bag", "out_bag"), ("--bag-storage", "bag_storage"))


def add_bag_options(p: argparse.ArgumentParser, results: str) -> None:
    """Adds ``--topic``, ``--out-bag`` and ``--bag-storage`` in their own group; ``results``
    says what the command writes into the new bag (for the help)."""
    g = p.add_argument_group(
        "ROS bags", "a source may be a ROS 1 bag (.bag) or a ROS 2 bag (a rosbag2 folder, or "
        "a .db3 / .mcap file); needs pip install \"tacswitch[ros]\"")
    g.add_argument("--topic", default=None, metavar="TOPIC",
                   help="the bag's image topic (sensor_msgs/Image or CompressedImage)")
    g.add_argument("--out-bag", default=None, metavar="PATH",
                   help=f"also write a new bag: every message of the input plus {results}, "
                        "with the frames' header stamps (a .bag file for a ROS 1 input, a "
                        "rosbag2 folder for a ROS 2 one; written atomically)")
    g.add_argument("--bag-storage", choices=("sqlite3", "mcap"), default=None,
                   help="ROS 2 --out-bag storage (default: the input's)")


def _no_bag_options(args: argparse.Namespace) -> None:
    for flag, attr in FLAGS:
        if getattr(args, attr, None) is not None:
            raise UsageError(f"{flag}: applies to a ROS bag source only")


def bag_source(source: str, args: argparse.Namespace, name: str = "source") -> Any:
    """The :class:`tacswitch.bags.BagSource` of ``source`` with ``--topic`` when it is a bag
    (its ``--out-bag`` checked), None otherwise (bag options then a usage error). A missing or
    wrong ``--topic`` and an unusable ``--out-bag`` are usage errors naming the option; a
    missing ``rosbags`` a one-line error naming the extra."""
    from tacswitch.bags import BagSource, check_output, is_bag

    if not is_bag(source):
        _no_bag_options(args)
        return None
    try:
        src = BagSource(source, args.topic, name=name, topic_name="--topic")
    except ImportError as exc:
        raise ValueError(str(exc)) from None
    except ValueError as exc:
        if str(exc).startswith("--topic:"):
            raise UsageError(str(exc)) from None
        raise
    if args.out_bag is not None:
        try:
            check_output(source, args.out_bag, args.bag_storage, "--out-bag")
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    elif args.bag_storage is not None:
        raise UsageError("--bag-storage: applies with --out-bag only")
    return src


def only_bag(inputs: list[str], args: argparse.Namespace) -> Any:
    """For the commands that take several inputs: the bag source when ``inputs`` holds a bag
    (it must be the only input), None otherwise."""
    from tacswitch.bags import is_bag

    bags = [i for i in inputs if is_bag(i)]
    if not bags:
        _no_bag_options(args)
        return None
    if len(inputs) > 1:
        raise UsageError(f"inputs: a ROS bag is read alone; give {bags[0]!r} on its own")
    return bag_source(bags[0], args, "inputs")


@contextlib.contextmanager
def bag_sink(src: Any, args: argparse.Namespace, out: str | Path | None = None
             ) -> Iterator[Any]:
    """The :class:`tacswitch.bags.BagSink` of ``--out-bag`` (or ``out``) for the bag source
    ``src``, or None when there is no bag to write."""
    target = args.out_bag if getattr(args, "out_bag", None) is not None else out
    if src is None or target is None:
        yield None
        return
    from tacswitch.bags import BagSink

    with BagSink(src.path, target, src.topic, storage=args.bag_storage,
                 name="--out-bag") as sink:
        yield sink


def motion_fields(points: Any, motion: Any, valid: Any = None) -> dict[str, Any]:
    """The ``PointCloud2`` fields of a motion field: rest ``x, y`` px, ``dx, dy`` px (NaN
    where not ``valid``) and ``valid``."""
    import numpy as np

    pts = np.asarray(points, np.float32).reshape(-1, 2)
    mot = np.asarray(motion, np.float32).reshape(-1, 2)
    ok = np.ones(len(pts), bool) if valid is None else np.asarray(valid, bool)
    return {"x": pts[:, 0], "y": pts[:, 1], "dx": np.where(ok, mot[:, 0], np.nan),
            "dy": np.where(ok, mot[:, 1], np.nan), "valid": ok.astype(np.float32)}
