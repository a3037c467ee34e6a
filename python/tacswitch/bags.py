"""ROS bags as a frame source and a result sink, through the pure-Python ``rosbags`` package
(optional extra: ``pip install "tacswitch[ros]"``; no ROS install needed).

Reading (:class:`BagSource`, :func:`read_frames`): the ``sensor_msgs/Image`` or
``sensor_msgs/CompressedImage`` messages of one topic of a ROS 1 bag (``.bag``) or a ROS 2 bag
(a rosbag2 folder with ``metadata.yaml``, or a bare ``.db3`` / ``.mcap`` file), decoded to BGR
uint8 (:func:`decode_image`) with their header stamps.

Writing (:class:`BagSink`): a new bag of the same kind (ROS 1 in, ROS 1 out; ROS 2 in, a rosbag2
folder out, in the input's storage by default) holding every message of the input, copied
byte for byte, plus result topics under the image topic, each result message at the log time
of its frame and with the frame's header (stamp and frame_id):

- ``<topic>/markerless``: ``sensor_msgs/Image``, ``bgr8``: the frame with the markers removed.
- ``<topic>/marker_motion`` (and ``<topic>/markers``): ``sensor_msgs/PointCloud2``, one point
  per marker with float32 fields ``x, y, z`` (the marker's rest position in image pixels, x
  right, y down, z = 0; pixels, not metres) and ``dx, dy`` (its motion, px; NaN when a tracked
  marker is lost) and ``valid`` (1 or 0). Chosen because it keeps the header stamp, holds
  exact per-marker numbers in named fields, and RViz and Foxglove both show it (colour the
  points by ``dx`` or ``dy``); ``geometry_msgs/PoseArray`` has no room for a motion and
  ``std_msgs/Float32MultiArray`` no header. ``<topic>/markers`` (``tacswitch markers``) has
  the fields ``x, y, z, area, contrast`` instead.
- ``<topic>/slip``: ``diagnostic_msgs/DiagnosticArray`` with one status named ``tacswitch
  slip``: level 1 (WARN) while slipping, 0 (OK) otherwise, and the values ``slip``, ``phase``
  and ``score``. Chosen over ``std_msgs/Bool`` because it keeps the header stamp; ``level``
  plots as a 0/1 signal (Foxglove: ``/topic.status[0].level``).

A bag is written to a temporary name beside the target and renamed into place when complete,
so an interrupted run never leaves a half-written bag under the target's name.

``rosbags`` is imported only when a bag is opened: ``import tacswitch`` never needs it.
"""

from __future__ import annotations

import os
import re
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: File suffixes of bag files: ROS 1, and ROS 2 storage files read without their folder.
BAG_SUFFIXES = (".bag", ".db3", ".mcap")
IMAGE_TYPE = "sensor_msgs/msg/Image"
COMPRESSED_TYPE = "sensor_msgs/msg/CompressedImage"
IMAGE_TYPES = (IMAGE_TYPE, COMPRESSED_TYPE)
#: ``sensor_msgs/Image`` encodings :func:`decode_image` reads (lower case).
RAW_ENCODINGS = ("bgr8", "rgb8", "mono8", "8uc1", "8uc3", "bgra8", "rgba8", "mono16", "16uc1",
                 "bayer_rggb8", "bayer_bggr8", "bayer_gbrg8", "bayer_grbg8")
#: Suffixes of the result topics (module doc).
MARKERLESS, MOTION, MARKERS, SLIP = "markerless", "marker_motion", "markers", "slip"
INSTALL_HINT = 'pip install "tacswitch[ros]"'


def is_bag(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` names a bag: a ``.bag`` / ``.db3`` / ``.mcap`` file, or a folder with a
    rosbag2 ``metadata.yaml``."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return p.suffix.lower() in BAG_SUFFIXES and p.is_file()


def bag_kind(path: str | os.PathLike[str]) -> tuple[str, str | None]:
    """``("ros1", None)`` or ``("ros2", storage)`` with storage ``"sqlite3"`` or ``"mcap"``."""
    p = Path(path)
    if p.is_dir():
        text = (p / "metadata.yaml").read_text(errors="replace")
        found = re.search(r"storage_identifier:\s*['\"]?(\w+)", text)
        return "ros2", (found.group(1) if found else "sqlite3")
    suffix = p.suffix.lower()
    if suffix == ".bag":
        return "ros1", None
    return "ros2", "mcap" if suffix == ".mcap" else "sqlite3"


def _rosbags(name: str) -> None:
    """``ImportError`` naming the argument and the extra when ``rosbags`` is missing."""
    try:
        import rosbags  # noqa: F401
    except ImportError:
        raise ImportError(f"{name}: reading and writing ROS bags needs the rosbags package: "
                          f"{INSTALL_HINT}") from None


def _open_reader(path: Path, name: str) -> Any:
    """An opened ``rosbags`` ``AnyReader`` of the bag ``path``; ``ValueError`` naming ``name``
    when it cannot be read."""
    _rosbags(name)
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
    try:
        reader.open()
    except Exception as exc:  # rosbags' own classes (ReaderError, AnyReaderError, ...)
        text = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise ValueError(f"{name}: cannot read the bag {str(path)!r} ({text})") from None
    return reader


def image_topics(reader: Any) -> dict[str, str]:
    """``{topic: message type}`` of the image topics of an opened reader."""
    return {c.topic: c.msgtype for c in reader.connections if c.msgtype in IMAGE_TYPES}


def _to_bgr8(img: NDArray[Any]) -> NDArray[np.uint8]:
    return np.ascontiguousarray(img, dtype=np.uint8)


def decode_image(msg: Any, msgtype: str, name: str = "source") -> NDArray[np.uint8] | None:
    """A ``sensor_msgs/Image`` or ``CompressedImage`` message as ``H x W x 3`` BGR uint8.

    Raw encodings: ``bgr8``, ``rgb8``, ``mono8``, ``bgra8``, ``rgba8``, ``mono16`` (scaled to
    8 bits as ``round(v / 257)``, which maps 0..65535 onto 0..255 and undoes the usual
    ``v * 257`` widening exactly), and ``bayer_rggb8`` / ``bayer_bggr8`` / ``bayer_gbrg8`` /
    ``bayer_grbg8`` (demosaiced by OpenCV). Compressed: whatever OpenCV decodes (JPEG, PNG;
    ``format`` such as ``"jpeg"`` or ``"rgb8; jpeg compressed bgr8"``: the decoder returns BGR
    either way). Returns None for a compressed payload that does not decode (a damaged
    message, counted as an unreadable frame); ``ValueError`` naming ``name`` for an encoding
    that is not a camera image (depth ``32FC1``, ``compressedDepth``, 16-bit Bayer, ...).
    """
    import cv2

    if msgtype == COMPRESSED_TYPE:
        fmt = str(msg.format).lower()
        if "compresseddepth" in fmt:
            raise ValueError(f"{name}: CompressedImage format {msg.format!r} is a depth image; "
                             "tacswitch reads colour or grey camera frames")
        buf = np.asarray(msg.data, np.uint8)
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR) if buf.size else None
        return None if out is None else _to_bgr8(out)
    enc = str(msg.encoding).lower()
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, np.uint8)
    wide = enc in ("mono16", "16uc1")
    channels = {"bgr8": 3, "rgb8": 3, "8uc3": 3, "bgra8": 4, "rgba8": 4}.get(enc, 1)
    if enc not in RAW_ENCODINGS:
        raise ValueError(f"{name}: Image encoding {msg.encoding!r} is not supported; tacswitch "
                         f"reads {', '.join(e for e in RAW_ENCODINGS if not e[0].isdigit())} "
                         "and compressed JPEG / PNG")
    row = w * channels * (2 if wide else 1)
    if h < 1 or w < 1 or step < row or data.size < step * (h - 1) + row:
        raise ValueError(f"{name}: Image message of {data.size} bytes does not hold {h} x {w} "
                         f"{msg.encoding} pixels (step {step})")
    if data.size < step * h:  # a last row without its padding
        data = np.concatenate([data, np.zeros(step * h - data.size, np.uint8)])
    rows = data[:step * h].reshape(h, step)[:, :row]
    if wide:
        big = bool(getattr(msg, "is_bigendian", 0))
        v = rows.copy().view(">u2" if big else "<u2").astype(np.uint32)
        grey = ((v * 2 + 257) // 514).astype(np.uint8)  # round(v / 257)
        return _to_bgr8(cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR))
    px = rows.reshape(h, w, channels) if channels > 1 else np.ascontiguousarray(rows)
    # OpenCV names a Bayer pattern by the second row's first two pixels, hence RGGB ->
    # BayerBG (the mapping cv_bridge uses).
    codes = {"rgb8": cv2.COLOR_RGB2BGR, "bgra8": cv2.COLOR_BGRA2BGR, "rgba8": cv2.COLOR_RGBA2BGR,
             "mono8": cv2.COLOR_GRAY2BGR, "8uc1": cv2.COLOR_GRAY2BGR,
             "bayer_rggb8": cv2.COLOR_BayerBG2BGR, "bayer_bggr8": cv2.COLOR_BayerRG2BGR,
             "bayer_gbrg8": cv2.COLOR_BayerGR2BGR, "bayer_grbg8": cv2.COLOR_BayerGB2BGR}
    if enc in codes:
        return _to_bgr8(cv2.cvtColor(np.ascontiguousarray(px), codes[enc]))
    return _to_bgr8(px.copy())


def header_stamp_ns(msg: Any) -> int:
    """The header stamp of a message, ns since the epoch."""
    stamp = msg.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


@dataclass(frozen=True)
class BagFrame:
    """Where a frame came from: its message's log time (ns, when the recorder received it),
    header stamp (ns) and header (the message's own, reused by the results)."""

    log_ns: int
    stamp_ns: int
    header: Any


class BagSource:
    """The frames of one image topic of a bag, in log-time order.

    Iterating yields BGR uint8 frames (None for a compressed message that does not decode);
    :attr:`frames` holds a :class:`BagFrame` for every item yielded so far, so the item at
    index ``i`` came from ``frames[i]``.

    Args:
        path: a ``.bag`` file, a rosbag2 folder, or a ``.db3`` / ``.mcap`` file.
        topic: the image topic (``sensor_msgs/Image`` or ``CompressedImage``).
        name: the argument named in errors (``source`` for the API; the CLI passes its own).
        topic_name: how errors name the topic argument (``topic``; the CLI: ``--topic``).

    Raises:
        ImportError: ``rosbags`` is not installed (names ``pip install "tacswitch[ros]"``).
        ValueError: the bag cannot be read, or ``topic`` is not an image topic of it (the
            message lists the image topics it has).
    """

    def __init__(self, path: str | os.PathLike[str], topic: str | None, *, name: str = "source",
                 topic_name: str = "topic") -> None:
        self.path = Path(path)
        self.name = name
        if not is_bag(self.path):
            raise ValueError(f"{name}: {str(path)!r} is not a bag (a .bag, .db3 or .mcap file, "
                             "or a rosbag2 folder with metadata.yaml)")
        self.kind, self.storage = bag_kind(self.path)
        reader = _open_reader(self.path, name)
        try:
            topics = image_topics(reader)
            count = sum(c.msgcount for c in reader.connections if c.topic == topic)
        finally:
            reader.close()
        if topic not in topics:
            have = ", ".join(sorted(topics)) or "none"
            what = "needs" if topic is None else f"{topic!r} is not"
            raise ValueError(f"{topic_name}: {what} an image topic of {str(path)!r} "
                             f"(Image or CompressedImage topics: {have})")
        self.topic = topic
        self.msgtype = topics[topic]
        self.count = count if count > 0 else None
        self.frames: list[BagFrame] = []

    def __len__(self) -> int:
        return self.count or 0

    def __iter__(self) -> Iterator[NDArray[np.uint8] | None]:
        reader = _open_reader(self.path, self.name)
        try:
            conns = [c for c in reader.connections if c.topic == self.topic]
            for conn, log_ns, raw in reader.messages(connections=conns):
                msg = reader.deserialize(raw, conn.msgtype)
                self.frames.append(BagFrame(int(log_ns), header_stamp_ns(msg), msg.header))
                yield decode_image(msg, conn.msgtype, self.name)
        finally:
            reader.close()


def read_frames(path: str | os.PathLike[str], topic: str
                ) -> Iterator[tuple[int, NDArray[np.uint8] | None]]:
    """Yields ``(header stamp ns, BGR uint8 frame)`` for every message of the image topic
    ``topic`` of a bag (frame None for a compressed message that does not decode). See
    :class:`BagSource` for the bags and errors."""
    src = BagSource(path, topic)
    for i, frame in enumerate(src):
        yield src.frames[i].stamp_ns, frame


def _temp_sibling(target: Path) -> Path:
    return target.with_name(f".{target.name}.tacswitch-part-{os.getpid()}")


def check_output(source: str | os.PathLike[str], out: str | os.PathLike[str],
                 storage: str | None = None, name: str = "out_bag") -> tuple[str, str | None]:
    """The ``(kind, storage)`` the bag ``out`` is written in for the bag ``source``;
    ``ValueError`` naming ``name`` for an ``out`` that cannot be one (a ROS 1 bag's output
    not named ``.bag``, a ROS 2 output named like a file, the input itself, an unknown
    ``storage``)."""
    kind, in_storage = bag_kind(source)
    target = Path(out)
    if target.resolve() == Path(source).resolve():
        raise ValueError(f"{name}: {str(out)!r} is the input bag; write the results to a new "
                         "bag")
    if kind == "ros1":
        if target.suffix.lower() != ".bag":
            raise ValueError(f"{name}: the input is a ROS 1 bag, so the output is one too: "
                             f"name it *.bag (got {str(out)!r})")
        if storage is not None:
            raise ValueError(f"{name}: a storage ({storage!r}) applies to ROS 2 bags only")
        if target.is_dir():
            raise ValueError(f"{name}: {str(out)!r} is a folder; give a .bag file name")
        return kind, None
    if target.suffix.lower() in BAG_SUFFIXES:
        raise ValueError(f"{name}: a ROS 2 bag is written as a rosbag2 folder (metadata.yaml "
                         f"and its storage file); give a folder name, not {str(out)!r}")
    if target.exists() and not (target.is_dir() and (not any(target.iterdir())
                                                     or is_bag(target))):
        raise ValueError(f"{name}: {str(out)!r} exists and is not a bag; give a new name")
    chosen = storage or in_storage
    if chosen not in ("sqlite3", "mcap"):
        raise ValueError(f"{name}: storage must be 'sqlite3' or 'mcap'; got {storage!r}")
    return kind, chosen


class BagSink:
    """A new bag: every message of ``source`` copied, plus result topics (module doc).

    Use as a context manager; results go in through :meth:`image`, :meth:`points` and
    :meth:`slip` with the :class:`BagFrame` of their frame, in the order of the frames. The
    input's messages are copied up to each result's log time as it arrives, so the output is
    in log-time order. Leaving the block without an error copies the rest and renames the
    finished bag onto ``out`` (replacing an older bag there); an error removes it.

    Args:
        source: the input bag (as :class:`BagSource` takes it).
        out: the new bag: a ``.bag`` file for a ROS 1 input, a folder for a ROS 2 input.
        topic: the image topic the results belong to (their topics are under it).
        storage: ROS 2 only: ``"sqlite3"`` or ``"mcap"`` (default: the input's).
        name: the argument named in errors.
    """

    def __init__(self, source: str | os.PathLike[str], out: str | os.PathLike[str], topic: str,
                 *, storage: str | None = None, name: str = "out_bag") -> None:
        _rosbags(name)
        self.source, self.out, self.topic, self.name = Path(source), Path(out), topic, name
        self.kind, self.storage = check_output(source, out, storage, name)
        self.written: dict[str, int] = {}

    # --- lifecycle ---------------------------------------------------------------------------

    def __enter__(self) -> BagSink:
        from rosbags.typesys import Stores, get_typestore

        self.tmp = _temp_sibling(self.out)
        _remove(self.tmp)
        self.out.parent.mkdir(parents=True, exist_ok=True)
        self.reader = _open_reader(self.source, self.name)
        self.store = get_typestore(Stores.ROS1_NOETIC if self.kind == "ros1"
                                   else Stores.ROS2_HUMBLE)
        if self.kind == "ros1":
            from rosbags.rosbag1 import Writer as Writer1

            self.writer: Any = Writer1(self.tmp)
        else:
            from rosbags.rosbag2 import StoragePlugin
            from rosbags.rosbag2 import Writer as Writer2

            plugin = StoragePlugin.MCAP if self.storage == "mcap" else StoragePlugin.SQLITE3
            self.writer = Writer2(self.tmp, version=8, storage_plugin=plugin)
        self.writer.open()
        self.copies: dict[int, Any] = {}
        for conn in self.reader.connections:
            self.copies[id(conn)] = self._copy_connection(conn)
        self.pending = self.reader.messages()
        self.next: Any = next(self.pending, None)
        self.results: dict[str, Any] = {}
        return self

    def __exit__(self, kind: Any, exc: Any, tb: Any) -> None:
        try:
            if kind is None:
                self._copy_until(None)
                self.writer.close()
                self.reader.close()
                _replace(self.tmp, self.out)
                return
        except BaseException:
            self._discard()
            raise
        self._discard()

    def _discard(self) -> None:
        for close in (getattr(self.writer, "abort", None), self.reader.close):
            try:
                if close is not None:
                    close()
            except Exception:  # cleaning up after the real error, which is raised
                pass
        _remove(self.tmp)

    # --- copying -----------------------------------------------------------------------------

    def _copy_connection(self, conn: Any) -> Any:
        if self.kind == "ros1":
            return self.writer.add_connection(conn.topic, conn.msgtype,
                                              msgdef=conn.msgdef.data or None,
                                              md5sum=conn.digest or None,
                                              callerid=conn.ext.callerid,
                                              latching=conn.ext.latching,
                                              typestore=self.reader.typestore)
        kw: dict[str, Any] = {"serialization_format": conn.ext.serialization_format,
                              "offered_qos_profiles": conn.ext.offered_qos_profiles}
        if conn.msgdef.data and conn.digest:
            kw |= {"msgdef": conn.msgdef.data, "rihs01": conn.digest}
        else:
            kw["typestore"] = self.reader.typestore
        return self.writer.add_connection(conn.topic, conn.msgtype, **kw)

    def _copy_until(self, log_ns: int | None) -> None:
        """Copies the input's messages logged at or before ``log_ns`` (None: all)."""
        while self.next is not None and (log_ns is None or self.next[1] <= log_ns):
            conn, t, raw = self.next
            self.writer.write(self.copies[id(conn)], t, raw)
            self.next = next(self.pending, None)

    # --- results -----------------------------------------------------------------------------

    def _write(self, suffix: str, msgtype: str, msg: Any, at: BagFrame) -> None:
        topic = f"{self.topic.rstrip('/')}/{suffix}"
        conn = self.results.get(topic)
        if conn is None:
            conn = self.results[topic] = self.writer.add_connection(topic, msgtype,
                                                                    typestore=self.store)
        self._copy_until(at.log_ns)
        data = (self.store.serialize_ros1(msg, msgtype) if self.kind == "ros1"
                else self.store.serialize_cdr(msg, msgtype))
        self.writer.write(conn, at.log_ns, data)
        self.written[topic] = self.written.get(topic, 0) + 1

    def _header(self, at: BagFrame) -> Any:
        t = self.store.types
        h = at.header
        stamp = t["builtin_interfaces/msg/Time"](sec=int(h.stamp.sec),
                                                 nanosec=int(h.stamp.nanosec))
        if self.kind == "ros1":
            return t["std_msgs/msg/Header"](seq=int(getattr(h, "seq", 0)), stamp=stamp,
                                            frame_id=str(h.frame_id))
        return t["std_msgs/msg/Header"](stamp=stamp, frame_id=str(h.frame_id))

    def image(self, at: BagFrame, img: NDArray[np.uint8], suffix: str = MARKERLESS) -> None:
        """``img`` (``H x W x 3`` BGR uint8) as a ``bgr8`` Image on ``<topic>/<suffix>``."""
        arr = np.ascontiguousarray(img, np.uint8)
        h, w = arr.shape[:2]
        msg = self.store.types[IMAGE_TYPE](header=self._header(at), height=h, width=w,
                                           encoding="bgr8", is_bigendian=0, step=w * 3,
                                           data=arr.reshape(-1))
        self._write(suffix, IMAGE_TYPE, msg, at)

    def points(self, at: BagFrame, fields: dict[str, NDArray[Any]], suffix: str = MOTION
               ) -> None:
        """One ``PointCloud2`` on ``<topic>/<suffix>``: a point per row, a float32 field per
        entry of ``fields`` (equal lengths; ``x``, ``y`` first, ``z`` = 0 added)."""
        t = self.store.types
        cols = {"x": fields["x"], "y": fields["y"], "z": np.zeros(len(fields["x"]))}
        cols |= {k: v for k, v in fields.items() if k not in cols}
        table = np.stack([np.asarray(v, np.float32) for v in cols.values()], axis=1) \
            if len(fields["x"]) else np.zeros((0, len(cols)), np.float32)
        step = 4 * len(cols)
        pf = [t["sensor_msgs/msg/PointField"](name=k, offset=4 * i, datatype=7, count=1)
              for i, k in enumerate(cols)]  # 7: FLOAT32
        data = np.ascontiguousarray(table.astype("<f4")).view(np.uint8).reshape(-1)
        msg = t["sensor_msgs/msg/PointCloud2"](
            header=self._header(at), height=1, width=len(table), fields=pf, is_bigendian=False,
            point_step=step, row_step=step * len(table), data=data,
            is_dense=bool(np.isfinite(table).all()))
        self._write(suffix, "sensor_msgs/msg/PointCloud2", msg, at)

    def slip(self, at: BagFrame, slip: bool, phase: str, score: float) -> None:
        """The slip state on ``<topic>/slip`` (module doc)."""
        t = self.store.types
        kv = t["diagnostic_msgs/msg/KeyValue"]
        status = t["diagnostic_msgs/msg/DiagnosticStatus"](
            level=1 if slip else 0, name="tacswitch slip",
            message="slip" if slip else "no slip", hardware_id=str(at.header.frame_id),
            values=[kv(key="slip", value=str(bool(slip)).lower()), kv(key="phase", value=phase),
                    kv(key="score", value="nan" if score != score else f"{score:.4f}")])
        msg = t["diagnostic_msgs/msg/DiagnosticArray"](header=self._header(at), status=[status])
        self._write(SLIP, "diagnostic_msgs/msg/DiagnosticArray", msg, at)


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    elif path.exists() or path.is_symlink():
        path.unlink()


def _replace(tmp: Path, target: Path) -> None:
    """Moves the finished bag ``tmp`` onto ``target``; an older bag folder there is moved
    aside first and removed after (``os.replace`` cannot replace a non-empty folder)."""
    old = None
    if target.is_dir():
        old = target.with_name(f".{target.name}.tacswitch-old-{os.getpid()}")
        _remove(old)
        os.replace(target, old)
    os.replace(tmp, target)
    if old is not None:
        _remove(old)
