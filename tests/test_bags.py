"""ROS bags as a source and a sink: real bags written with ``rosbags`` (ROS 2 sqlite3 and MCAP,
ROS 1) from simulated frames, read back, and run through the CLI."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

import tacswitch as ts
from tacswitch.cli import main

pytest.importorskip("rosbags", reason="needs the rosbags package (pip install 'tacswitch[ros]')")

from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from tacswitch import bags

TOPIC = "/gelsight/image_raw"
KINDS = ("sqlite3", "mcap", "ros1")
T0 = 1_700_000_000


@pytest.fixture(scope="module")
def grasp() -> list[np.ndarray]:
    return list(ts.sim.grasp_sequence("gelsight_mini", "slip", n_frames=8, seed=2).frames)


def _image_msg(store: Any, header: Any, img: np.ndarray, encoding: str, pad: int = 0) -> Any:
    """``img`` (BGR) as a ``sensor_msgs/Image`` of ``encoding`` (``pad`` bytes per row)."""
    e = encoding
    if e == "rgb8":
        px = img[..., ::-1]
    elif e == "mono8":
        px = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    elif e == "bgra8":
        px = cv2.cvtColor(img, cv2.COLOR_BGR2BGRA)
    elif e == "rgba8":
        px = cv2.cvtColor(img, cv2.COLOR_BGR2RGBA)
    elif e == "mono16":
        px = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype("<u2") * 257
    elif e.startswith("bayer_"):
        px = _mosaic(img, e[6:10])
    else:
        px = img
    h, w = img.shape[:2]
    raw = np.ascontiguousarray(px).view(np.uint8).reshape(h, -1)
    rows = np.zeros((h, raw.shape[1] + pad), np.uint8)
    rows[:, :raw.shape[1]] = raw
    return store.types["sensor_msgs/msg/Image"](
        header=header, height=h, width=w, encoding=encoding, is_bigendian=0,
        step=rows.shape[1], data=rows.reshape(-1))


def _mosaic(img: np.ndarray, pattern: str) -> np.ndarray:
    """A Bayer mosaic of ``img`` (BGR): ``pattern`` names the colours of the 2 x 2 cell row by
    row, as ROS encodings do (``rggb``: R at (0, 0), B at (1, 1))."""
    index = {"b": 0, "g": 1, "r": 2}
    out = np.zeros(img.shape[:2], np.uint8)
    for k, c in enumerate(pattern):
        dy, dx = divmod(k, 2)
        out[dy::2, dx::2] = img[dy::2, dx::2, index[c]]
    return out


def make_bag(path: Path, kind: str, frames: list[np.ndarray], encoding: str = "bgr8",
             pad: int = 0) -> list[int]:
    """Writes ``frames`` on :data:`TOPIC` (and a String topic between them) into a new bag;
    returns the header stamps (ns). Log times lag the stamps by 3 ms, as a recorder's do."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin, Writer

    ros1 = kind == "ros1"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    t = store.types
    ser = store.serialize_ros1 if ros1 else store.serialize_cdr
    writer: Any = (Writer1(path) if ros1 else
                   Writer(path, version=9, storage_plugin=StoragePlugin.MCAP if kind == "mcap"
                          else StoragePlugin.SQLITE3))
    stamps = []
    compressed = encoding in ("jpeg", "png")
    msgtype = "sensor_msgs/msg/CompressedImage" if compressed else "sensor_msgs/msg/Image"
    with writer:
        cam = writer.add_connection(TOPIC, msgtype, typestore=store)
        other = writer.add_connection("/gripper/state", "std_msgs/msg/String", typestore=store)
        for i, img in enumerate(frames):
            sec, nsec = T0 + i // 30, (i % 30) * 33_333_333 + 7
            stamps.append(sec * 1_000_000_000 + nsec)
            stamp = t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
            header = (t["std_msgs/msg/Header"](seq=i, stamp=stamp, frame_id="gel_optical")
                      if ros1 else t["std_msgs/msg/Header"](stamp=stamp, frame_id="gel_optical"))
            if compressed:
                _ok, buf = cv2.imencode(f".{'jpg' if encoding == 'jpeg' else 'png'}", img)
                msg = t[msgtype](header=header, format=encoding,
                                 data=np.asarray(buf, np.uint8).reshape(-1))
            else:
                msg = _image_msg(store, header, img, encoding, pad)
            log = stamps[-1] + 3_000_000
            writer.write(cam, log, ser(msg, msgtype))
            writer.write(other, log + 1, ser(t["std_msgs/msg/String"](data=f"state {i}"),
                                             "std_msgs/msg/String"))
    return stamps


def bag_path(tmp: Path, kind: str, name: str = "in") -> Path:
    return tmp / (f"{name}.bag" if kind == "ros1" else name)


# ---- reading --------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("encoding", ["bgr8", "rgb8", "mono8", "bgra8", "rgba8", "mono16",
                                      "png"])
def test_exact_encodings_round_trip(tmp_path: Path, grasp: list[np.ndarray], kind: str,
                                    encoding: str) -> None:
    frames = grasp[:2]
    path = bag_path(tmp_path, kind)
    stamps = make_bag(path, kind, frames, encoding, pad=8 if encoding == "rgb8" else 0)
    got = list(bags.read_frames(path, TOPIC))
    assert [s for s, _ in got] == stamps
    for (_, frame), img in zip(got, frames, strict=True):
        want = (cv2.cvtColor(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), cv2.COLOR_GRAY2BGR)
                if encoding.startswith("mono") else img)
        assert frame is not None and frame.dtype == np.uint8 and frame.shape == img.shape
        assert np.array_equal(frame, want)


@pytest.mark.parametrize("pattern", ["rggb", "bggr", "gbrg", "grbg"])
def test_bayer_encodings_are_demosaiced_to_the_right_colours(tmp_path: Path, pattern: str
                                                             ) -> None:
    # A smooth colour image: demosaicing is near exact, a swapped pattern is far off.
    yy, xx = np.mgrid[0:48, 0:64].astype(np.float32)
    img = np.dstack([40 + 2 * xx, 120 + yy, 220 - 2 * yy]).astype(np.uint8)
    path = bag_path(tmp_path, "mcap")
    make_bag(path, "mcap", [img], f"bayer_{pattern}8")
    (_, frame), = bags.read_frames(path, TOPIC)
    inner = (slice(4, -4), slice(4, -4))
    err = np.abs(frame[inner].astype(int) - img[inner]).mean(axis=(0, 1))
    assert (err < 3).all(), err


def test_jpeg_and_bare_storage_files(tmp_path: Path, grasp: list[np.ndarray]) -> None:
    path = bag_path(tmp_path, "mcap")
    make_bag(path, "mcap", grasp[:2], "jpeg")
    frames = [f for _, f in bags.read_frames(path, TOPIC)]
    assert all(np.abs(f.astype(int) - g).mean() < 3 for f, g in zip(frames, grasp, strict=False))
    # A storage file without its folder reads the same.
    (bare,) = path.glob("*.mcap")
    assert bags.is_bag(bare) and bags.bag_kind(bare) == ("ros2", "mcap")
    assert all(np.array_equal(a, b) for (_, a), b in
               zip(bags.read_frames(bare, TOPIC), frames, strict=True))
    db = bag_path(tmp_path, "sqlite3", "db")
    make_bag(db, "sqlite3", grasp[:1])
    (db3,) = db.glob("*.db3")
    assert np.array_equal(next(bags.read_frames(db3, TOPIC))[1], grasp[0])


def test_reading_errors_are_one_line(tmp_path: Path, grasp: list[np.ndarray],
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    path = bag_path(tmp_path, "sqlite3")
    make_bag(path, "sqlite3", grasp[:1])
    with pytest.raises(ValueError, match=r"^topic: '/nope' is not an image topic .*"
                                         r"Image or CompressedImage topics: /gelsight/image_raw"):
        bags.BagSource(path, "/nope")
    odd = bag_path(tmp_path, "sqlite3", "depth")
    store = get_typestore(Stores.ROS2_HUMBLE)
    msg = store.types["sensor_msgs/msg/Image"](
        header=store.types["std_msgs/msg/Header"](
            stamp=store.types["builtin_interfaces/msg/Time"](sec=1, nanosec=0), frame_id=""),
        height=2, width=2, encoding="32FC1", is_bigendian=0, step=8, data=np.zeros(16, np.uint8))
    with pytest.raises(ValueError, match=r"^source: Image encoding '32FC1' is not supported"):
        bags.decode_image(msg, bags.IMAGE_TYPE)
    del odd
    import sys

    monkeypatch.setitem(sys.modules, "rosbags", None)
    with pytest.raises(ImportError, match=r'pip install "tacswitch\[ros\]"'):
        bags.BagSource(path, TOPIC)


def test_import_tacswitch_does_not_import_rosbags() -> None:
    import subprocess
    import sys

    code = "import sys, tacswitch, tacswitch.bags; print('rosbags' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


# ---- the CLI --------------------------------------------------------------------------------

def read_bag(path: Path) -> dict[str, list[tuple[int, Any, str]]]:
    """``{topic: [(log ns, message, msgtype)]}`` of a bag, read with rosbags."""
    out: dict[str, list[tuple[int, Any, str]]] = {}
    with AnyReader([path]) as reader:
        for conn, t, raw in reader.messages():
            out.setdefault(conn.topic, []).append(
                (t, reader.deserialize(raw, conn.msgtype), conn.msgtype))
    return out


def stamp(msg: Any) -> int:
    return bags.header_stamp_ns(msg)


def cloud(msg: Any) -> dict[str, np.ndarray]:
    names = [f.name for f in msg.fields]
    table = np.asarray(msg.data, np.uint8).view("<f4").reshape(msg.width, len(names))
    return {n: table[:, i] for i, n in enumerate(names)}


def check_copied(out: dict[str, list[tuple[int, Any, str]]], stamps: list[int]) -> None:
    assert [stamp(m) for _, m, _ in out[TOPIC]] == stamps
    assert [m.data for _, m, _ in out["/gripper/state"]] == [f"state {i}"
                                                              for i in range(len(stamps))]


@pytest.mark.parametrize("kind", KINDS)
def test_remove_markers_writes_a_bag_with_markerless_frames(
        tmp_path: Path, grasp: list[np.ndarray], kind: str) -> None:
    frames = grasp[:3]
    src = bag_path(tmp_path, kind)
    stamps = make_bag(src, kind, frames, "rgb8")
    target = bag_path(tmp_path, kind, "out")
    assert main(["remove-markers", str(src), "--topic", TOPIC, "-o", str(tmp_path / "o"),
                 "--out-bag", str(target), "-q"]) == 0
    out = read_bag(target)
    check_copied(out, stamps)
    clean = out[f"{TOPIC}/markerless"]
    assert [stamp(m) for _, m, _ in clean] == stamps
    assert [t for t, _, _ in clean] == [t for t, _, _ in out[TOPIC]]  # the frames' log times
    for (_, m, typ), img in zip(clean, frames, strict=True):
        assert typ == bags.IMAGE_TYPE and m.encoding == "bgr8"
        assert m.header.frame_id == "gel_optical"
        got = np.asarray(m.data, np.uint8).reshape(m.height, m.width, 3)
        assert np.array_equal(got, ts.remove_markers(img))
    assert not [p for p in tmp_path.iterdir() if "tacswitch-part" in p.name]


def test_remove_markers_default_output_and_storage(tmp_path: Path,
                                                    grasp: list[np.ndarray]) -> None:
    src = bag_path(tmp_path, "sqlite3", "run1")
    make_bag(src, "sqlite3", grasp[:1])
    assert main(["remove-markers", str(src), "--topic", TOPIC, "-o", str(tmp_path / "o"),
                 "-q"]) == 0
    assert bags.bag_kind(tmp_path / "o" / "run1") == ("ros2", "sqlite3")
    # Again, into MCAP: the older bag at the target is replaced whole.
    assert main(["remove-markers", str(src), "--topic", TOPIC, "-o", str(tmp_path / "o"),
                 "--out-bag", str(tmp_path / "o" / "run1"), "--bag-storage", "mcap",
                 "-q"]) == 0
    assert bags.bag_kind(tmp_path / "o" / "run1") == ("ros2", "mcap")
    assert len(read_bag(tmp_path / "o" / "run1")[f"{TOPIC}/markerless"]) == 1


def test_a_hybrid_removal_of_a_bag_takes_the_settled_frame_as_its_reference(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # A dark first frame (exposure settling), then the gel at rest, then a grasp: as for a
    # video, the no-contact reference is frame 1, not frame 0.
    seq = ts.sim.grasp_sequence("gelsight_mini", "hold", n_frames=8, seed=3)
    frames = [(0.6 * seq.reference).astype(np.uint8)] + [seq.reference] * 6 + list(seq.frames)
    src = bag_path(tmp_path, "sqlite3")
    make_bag(src, "sqlite3", frames)
    target = bag_path(tmp_path, "sqlite3", "out")
    assert main(["remove-markers", str(src), "--topic", TOPIC, "-o", str(tmp_path / "o"),
                 "--out-bag", str(target), "--method", "hybrid"]) == 0
    assert "hybrid reference (no contact) = frame 1 (the first after the camera settled)" in (
        capsys.readouterr().out)
    clean = read_bag(target)[f"{TOPIC}/markerless"]
    assert len(clean) == len(frames)  # every frame is still removed, in order
    _, m, _ = clean[-1]
    got = np.asarray(m.data, np.uint8).reshape(m.height, m.width, 3)
    np.testing.assert_array_equal(got, ts.remove_markers(frames[-1], method="hybrid",
                                                         ref=frames[1]))


@pytest.mark.parametrize("kind", KINDS)
def test_slip_writes_slip_state_and_motion(tmp_path: Path, grasp: list[np.ndarray],
                                           kind: str) -> None:
    src = bag_path(tmp_path, kind)
    stamps = make_bag(src, kind, grasp, "bgr8")
    target = bag_path(tmp_path, kind, "out")
    log = tmp_path / "slip.csv"
    assert main(["slip", str(src), "--topic", TOPIC, "--log", str(log), "--out-bag",
                 str(target), "-q"]) == 0
    import csv

    rows = list(csv.DictReader(log.open()))
    out = read_bag(target)
    check_copied(out, stamps)
    states = out[f"{TOPIC}/slip"]
    assert [stamp(m) for _, m, _ in states] == [stamps[int(r["frame"])] for r in rows]
    for (_, m, typ), r in zip(states, rows, strict=True):
        assert typ == "diagnostic_msgs/msg/DiagnosticArray"
        (status,) = m.status
        assert status.level == int(r["slip"])
        values = {kv.key: kv.value for kv in status.values}
        assert values["slip"] == ("true" if r["slip"] == "1" else "false")
        assert values["phase"] == r["phase"]
    motion = out[f"{TOPIC}/marker_motion"]
    assert len(motion) == len(rows)
    first = cloud(motion[0][1])
    assert np.allclose(first["dx"], 0) and np.allclose(first["dy"], 0)  # the rest frame
    assert np.abs(cloud(motion[-1][1])["dx"]).max() > 0.5  # the slip moves the markers


@pytest.mark.parametrize("kind", KINDS)
def test_motion_writes_marker_motion_matching_its_csv(tmp_path: Path, kind: str) -> None:
    seq = ts.sim.grasp_sequence("gelsight_mini", "slip", n_frames=8, seed=2)
    frames = [ts.remove_markers(f) for f in seq.frames[:4]]
    src = bag_path(tmp_path, kind)
    stamps = make_bag(src, kind, frames, "mono8" if kind == "ros1" else "bgr8")
    target = bag_path(tmp_path, kind, "out")
    assert main(["motion", str(src), "--topic", TOPIC, "-o", str(tmp_path / "m"),
                 "--out-bag", str(target), "-q"]) == 0
    import csv

    rows = list(csv.DictReader((tmp_path / "m" / f"{src.stem}.csv").open()))
    out = read_bag(target)
    check_copied(out, stamps)
    msgs = out[f"{TOPIC}/marker_motion"]
    assert [stamp(m) for _, m, _ in msgs] == stamps
    for i, (_, m, typ) in enumerate(msgs):
        assert typ == "sensor_msgs/msg/PointCloud2" and m.header.frame_id == "gel_optical"
        c = cloud(m)
        assert [f.name for f in m.fields] == ["x", "y", "z", "dx", "dy", "valid"]
        mine = [r for r in rows if int(r["frame"]) == i]
        assert np.allclose(c["x"], [float(r["x"]) for r in mine], atol=1e-3)
        assert np.allclose(c["dx"], [float(r["dx"]) for r in mine], atol=1e-4)
        assert np.allclose(c["dy"], [float(r["dy"]) for r in mine], atol=1e-4)


def test_track_reads_a_bag_like_a_video(tmp_path: Path, grasp: list[np.ndarray]) -> None:
    src = bag_path(tmp_path, "mcap")
    stamps = make_bag(src, "mcap", grasp[:3])
    target = tmp_path / "out"
    assert main(["track", str(src), "--topic", TOPIC, "-o", str(tmp_path / "t.csv"),
                 "--out-bag", str(target), "-q"]) == 0
    msgs = read_bag(target)[f"{TOPIC}/marker_motion"]
    assert [stamp(m) for _, m, _ in msgs] == stamps
    assert (cloud(msgs[0][1])["valid"] == 1).all()


def test_cli_bag_usage_errors(tmp_path: Path, grasp: list[np.ndarray],
                              capsys: pytest.CaptureFixture[str]) -> None:
    src = bag_path(tmp_path, "ros1")
    make_bag(src, "ros1", grasp[:1])
    ros2 = bag_path(tmp_path, "mcap", "r2")
    make_bag(ros2, "mcap", grasp[:1])
    img = tmp_path / "f.png"
    cv2.imwrite(str(img), grasp[0])
    cases = [
        (["slip", str(src)], "--topic: needs an image topic of", 2),
        (["slip", str(src), "--topic", "/x"], "Image or CompressedImage topics: "
                                              "/gelsight/image_raw", 2),
        (["motion", str(src), "--topic", TOPIC, "--out-bag", str(tmp_path / "o")],
         "--out-bag: the input is a ROS 1 bag", 2),
        (["track", str(ros2), "--topic", TOPIC, "--out-bag", str(tmp_path / "o.mcap")],
         "--out-bag: a ROS 2 bag is written as a rosbag2 folder", 2),
        (["track", str(ros2), "--topic", TOPIC, "--out-bag", str(ros2)],
         "--out-bag: ", 2),
        (["slip", str(img), "--topic", TOPIC], "--topic: applies to a ROS bag source only", 2),
        (["remove-markers", str(src), str(img), "--topic", TOPIC, "-o", str(tmp_path / "o")],
         "inputs: a ROS bag is read alone", 2),
    ]
    for argv, needle, code in cases:
        assert main(argv) == code, argv
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and needle in err, (argv, err)


def test_cli_without_rosbags_names_the_extra(tmp_path: Path, grasp: list[np.ndarray],
                                             monkeypatch: pytest.MonkeyPatch,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    import sys

    src = bag_path(tmp_path, "sqlite3")
    make_bag(src, "sqlite3", grasp[:1])
    monkeypatch.setitem(sys.modules, "rosbags", None)
    assert main(["slip", str(src), "--topic", TOPIC]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and 'pip install "tacswitch[ros]"' in err, err


def test_markers_reads_one_frame_and_writes_every_frame(tmp_path: Path,
                                                         grasp: list[np.ndarray]) -> None:
    src = bag_path(tmp_path, "ros1")
    stamps = make_bag(src, "ros1", grasp[:3], "bgra8")
    assert main(["markers", str(src), "--topic", TOPIC, "-o", str(tmp_path / "m"), "--frame",
                 "1", "-q", "--out-bag", str(tmp_path / "out.bag")]) == 0
    import csv

    rows = list(csv.DictReader((tmp_path / "m" / "in.csv").open()))
    want = ts.extract_markers(grasp[1])
    assert len(rows) == len(want) > 0
    msgs = read_bag(tmp_path / "out.bag")[f"{TOPIC}/markers"]
    assert [stamp(m) for _, m, _ in msgs] == stamps
    c = cloud(msgs[1][1])
    assert np.allclose(c["x"], want.centres[:, 0]) and np.allclose(c["area"], want.areas)
