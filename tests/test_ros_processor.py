"""The live node's processor (tacswitch.ros.processor) end to end with the real ROS 2 message
types of ``rosbags``, built from simulated grasps; the converter; the node's entry point
without rclpy. ROS 2 itself is not installed here (docs/ros.md, "Live node")."""

from __future__ import annotations

import array
import dataclasses
import subprocess
import sys
from functools import cache
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

pytest.importorskip("rosbags", reason="the ROS message types come from rosbags "
                                      "(pip install \"tacswitch[ros]\")")

import tacswitch as ts
import tacswitch.sim
from tacswitch.ros import processor as proc
from tacswitch.ros.convert import from_ros, to_ros
from tacswitch.ros.processor import ProcessorConfig, TactileProcessor, process_all

N = 30
T0 = 1_700_000_000_000_000_000
DT = 33_333_333


@cache
def grasp(kind: str) -> tuple[np.ndarray, ...]:
    return tuple(ts.sim.grasp_sequence("gelsight_mini", kind, n_frames=N, seed=3).frames)


@cache
def store() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def header(i: int, t0: int = T0) -> Any:
    t = store().types
    ns = t0 + i * DT
    return t["std_msgs/msg/Header"](
        stamp=t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9),
        frame_id="gel")


def message(frame: np.ndarray, i: int, encoding: str, t0: int = T0) -> Any:
    """``frame`` (BGR) as a rosbags Image (``bgr8``, ``rgb8``, ``mono8``) or CompressedImage
    (``jpeg``)."""
    t = store().types
    if encoding == "jpeg":
        ok, buf = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 95])
        assert ok
        return t["sensor_msgs/msg/CompressedImage"](header=header(i, t0), format="jpeg",
                                                    data=buf.reshape(-1))
    px = {"bgr8": frame, "rgb8": frame[..., ::-1],
          "mono8": cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)}[encoding]
    px = np.ascontiguousarray(px)
    h, w = px.shape[:2]
    return t["sensor_msgs/msg/Image"](header=header(i, t0), height=h, width=w,
                                      encoding=encoding, is_bigendian=0,
                                      step=px.strides[0], data=px.reshape(-1))


def decoded(frame: np.ndarray, encoding: str) -> np.ndarray:
    """What the processor sees of ``frame`` sent as ``encoding``."""
    from tacswitch.bags import decode_image

    msg = message(frame, 0, encoding)
    return decode_image(msg, msg.__msgtype__)


def stamp(msg: Any) -> int:
    return int(msg.header.stamp.sec) * 10**9 + int(msg.header.stamp.nanosec)


def cloud(msg: Any) -> dict[str, np.ndarray]:
    names = [f.name for f in msg.fields]
    table = np.frombuffer(msg.data.tobytes(), "<f4").reshape(int(msg.width), len(names))
    return {n: table[:, i] for i, n in enumerate(names)}


def by_name(outputs: list[proc.Output], name: str) -> list[proc.Output]:
    return [o for o in outputs if o.name == name]


# --- end to end ----------------------------------------------------------------------------


@pytest.mark.parametrize("encoding", ["bgr8", "rgb8", "mono8", "jpeg"])
def test_markers_end_to_end_matches_the_library(encoding: str) -> None:
    frames = grasp("slip")
    p = TactileProcessor(look_ahead=1)
    out = process_all(p, [message(f, i, encoding) for i, f in enumerate(frames)])
    want = [T0 + i * DT for i in range(N)]
    for name, msgtype in (("markerless", "sensor_msgs/msg/Image"),
                          ("motion", "sensor_msgs/msg/PointCloud2"),
                          ("slip", "diagnostic_msgs/msg/DiagnosticArray")):
        got = by_name(out, name)
        assert [o.stamp_ns for o in got] == want, name
        assert [stamp(o.msg) for o in got] == want, name
        assert all(o.msgtype == msgtype == o.msg.__msgtype__ for o in got)
        assert all(o.msg.header.frame_id == "gel" for o in got)
    # The same classes run directly on the frames as decoded.
    seen = [decoded(f, encoding) for f in frames]
    tracker = ts.MarkerTracker(seen[0])
    detector = ts.GraspSlipDetector(tracker.reference, image_width=seen[0].shape[1])
    for f, m, s, img in zip(seen, by_name(out, "motion"), by_name(out, "slip"),
                            by_name(out, "markerless"), strict=True):
        motion, valid = tracker.update(f)
        c = cloud(m.msg)
        np.testing.assert_array_equal(c["x"], tracker.reference[:, 0])
        np.testing.assert_array_equal(c["dx"], np.where(valid, motion[:, 0], np.nan))
        np.testing.assert_array_equal(c["dy"], np.where(valid, motion[:, 1], np.nan))
        np.testing.assert_array_equal(c["valid"], valid.astype(np.float32))
        st = detector.update(motion, valid)
        assert s.msg.status[0].level == int(st.slip)
        assert img.msg.encoding == "bgr8"
        np.testing.assert_array_equal(img.msg.data.reshape(f.shape), ts.remove_markers(f))
    assert any(s.msg.status[0].level == 1 for s in by_name(out, "slip"))


@pytest.mark.parametrize("rule", ["learned", "paper"])
def test_slip_on_a_slip_and_not_on_a_hold(rule: str) -> None:
    flagged = {}
    for kind in ("slip", "hold"):
        p = TactileProcessor(rule=rule, outputs=["slip"], look_ahead=1)
        out = process_all(p, [message(f, i, "bgr8") for i, f in enumerate(grasp(kind))])
        assert {o.name for o in out} == {"slip"}
        flagged[kind] = sum(o.msg.status[0].level for o in out)
    assert flagged["slip"] > 0
    assert flagged["hold"] == 0


def test_markerless_motion_matches_markerless_tracker() -> None:
    frames = grasp("slip")[:10]
    p = TactileProcessor(motion="markerless", outputs=["motion", "slip"])
    out = process_all(p, [message(f, i, "bgr8") for i, f in enumerate(frames)])
    # With the learned slip output, the plain flow (of the preset, with the frame-to-frame
    # weight) the markerless scorer was trained on.
    from tacswitch.grasp.detector import SCORER_FLOW_PRESET, SCORER_FRAME_TO_FRAME

    tracker = ts.MarkerlessTracker(frames[0], suppress_imprint=False, preset=SCORER_FLOW_PRESET,
                                   anchor="rest", frame_to_frame=SCORER_FRAME_TO_FRAME)
    assert p.tracker.anchor == "rest"  # type: ignore[attr-defined]
    assert p.tracker.frame_to_frame == SCORER_FRAME_TO_FRAME  # type: ignore[attr-defined]
    motions = by_name(out, "motion")
    assert [o.stamp_ns for o in motions] == [T0 + i * DT for i in range(10)]
    assert len(by_name(out, "slip")) == 10
    for f, m in zip(frames, motions, strict=True):
        c = cloud(m.msg)
        want = tracker.update(f)
        np.testing.assert_array_equal(np.stack([c["dx"], c["dy"]], 1), want)
        np.testing.assert_array_equal(np.stack([c["x"], c["y"]], 1), tracker.centres)



def test_markerless_slip_by_the_paper_rule_reads_the_flow_from_rest() -> None:
    # The contact anchor follows an object that slides over the gel: slip reads from rest.
    frames = grasp("slip")[:3]
    p = TactileProcessor(motion="markerless", outputs=["motion", "slip"], rule="paper")
    process_all(p, [message(f, i, "bgr8") for i, f in enumerate(frames)])
    assert p.tracker.anchor == "rest" and p.tracker.suppress_imprint  # type: ignore[attr-defined]


def test_the_anchor_parameter_reaches_the_markerless_tracker() -> None:
    frames = grasp("slip")[:3]
    for outputs, anchor, want in ((["motion"], "auto", "contact"), (["motion"], "rest", "rest"),
                                  (["motion", "slip"], "auto", "rest"),
                                  (["motion", "slip"], "rest", "rest")):
        p = TactileProcessor(motion="markerless", outputs=outputs, anchor=anchor)
        process_all(p, [message(f, i, "bgr8") for i, f in enumerate(frames)])
        assert p.tracker.anchor == want, (outputs, anchor)  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match=r"^anchor: applies to motion 'markerless' only$"):
        TactileProcessor(motion="markers", anchor="rest")
    # rest_frames reaches the tracker too (without the slip output, which reads the frame as
    # given).
    for n in (1, 16):
        p = TactileProcessor(motion="markerless", outputs=["motion"], rest_frames=n)
        process_all(p, [message(f, i, "bgr8") for i, f in enumerate(frames)])
        assert p.tracker.rest_frames == n  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match=r"^anchor: the slip output reads the motion"):
        TactileProcessor(motion="markerless", outputs=["motion", "slip"], anchor="contact")
    with pytest.raises(ValueError, match=r"^anchor: one of auto, contact, rest; got 'first'$"):
        TactileProcessor(motion="markerless", anchor="first")


def test_markerless_motion_alone_suppresses_the_imprint() -> None:
    frames = grasp("slip")[:6]
    p = TactileProcessor(motion="markerless", outputs=["motion"])
    motions = by_name(process_all(p, [message(f, i, "bgr8") for i, f in enumerate(frames)]),
                      "motion")
    tracker = ts.MarkerlessTracker(frames[0])  # the defaults: imprint suppressed, contact anchor
    assert tracker.suppress_imprint and tracker.anchor == "contact"
    for f, m in zip(frames, motions, strict=True):
        c = cloud(m.msg)
        np.testing.assert_array_equal(np.stack([c["dx"], c["dy"]], 1), tracker.update(f))

# --- reference capture and the stream's accidents -------------------------------------------


def test_blank_first_frames_are_skipped_by_the_cli_rule() -> None:
    from tacswitch.cli import rest_frame

    assert (proc.LOOK_AHEAD, proc.USABLE_FRACTION) == (rest_frame.LOOK_AHEAD,
                                                      rest_frame.USABLE_FRACTION)
    frames = grasp("hold")
    blank = np.full_like(frames[0], 128)
    stream = [blank, blank, *frames[:8]]
    warned: list[str] = []
    p = TactileProcessor(look_ahead=6, outputs=["motion", "markerless"], warn=warned.append)
    out = []
    for i, f in enumerate(stream):
        got = p.process(message(f, i, "bgr8"))
        # The markerless image comes at once; the motion waits for the look-ahead.
        assert [o.name for o in got if o.name == "markerless"] == ["markerless"]
        out += got
    out += p.flush()
    rest, _ = rest_frame.choose_rest_frame(iter(stream[:6]), lambda f: len(ts.extract_markers(f)),
                                           source="x", max_frames=6)
    assert rest is not None and rest.index == 2
    motions = by_name(out, "motion")
    assert [o.stamp_ns for o in motions] == [T0 + i * DT for i in range(2, len(stream))]
    assert np.all(cloud(motions[0].msg)["dx"][cloud(motions[0].msg)["valid"] > 0] == 0)
    assert p.stats["before_reference"] == 2
    assert any("frame 2" in w for w in warned)


def test_nth_frame_and_service_reference() -> None:
    frames = grasp("slip")[:8]
    p = TactileProcessor(reference="frame", reference_frame=3, outputs=["motion"])
    out = process_all(p, [message(f, i, "bgr8") for i, f in enumerate(frames)])
    assert [o.stamp_ns for o in out] == [T0 + i * DT for i in range(3, 8)]
    tracker = ts.MarkerTracker(frames[3])
    np.testing.assert_array_equal(cloud(out[0].msg)["x"], tracker.reference[:, 0])

    p = TactileProcessor(reference="service", outputs=["motion", "slip"])
    assert p.process(message(frames[0], 0, "bgr8")) == []
    assert p.waiting
    p.recapture()
    got = p.process(message(frames[1], 1, "bgr8"))
    assert [o.name for o in got] == ["motion", "slip"]
    assert p.reference_stamp_ns == T0 + DT
    # A recapture later restarts from the next frame: its motion is zero again.
    p.process(message(frames[5], 5, "bgr8"))
    p.recapture()
    got = p.process(message(frames[6], 6, "bgr8"))
    c = cloud(got[0].msg)
    assert p.reference_stamp_ns == T0 + 6 * DT
    assert np.all(c["dx"][c["valid"] > 0] == 0)


def test_size_change_resets_and_dropped_and_undecodable_frames_are_counted() -> None:
    frames = grasp("hold")
    warned: list[str] = []
    p = TactileProcessor(look_ahead=1, outputs=["motion"], warn=warned.append)
    # Frames 0-5, then 6 and 7 dropped, then 8-9.
    for i in [0, 1, 2, 3, 4, 5, 8, 9]:
        assert len(p.process(message(frames[i], i, "bgr8"))) == 1
    assert p.stats["dropped"] == 2
    bad = store().types["sensor_msgs/msg/CompressedImage"](header=header(10), format="jpeg",
                                                           data=np.zeros(10, np.uint8))
    assert p.process(bad) == []
    assert p.stats["undecodable"] == 1
    small = np.ascontiguousarray(cv2.resize(frames[11], (160, 120)))
    got = p.process(message(small, 11, "bgr8"))
    assert p.stats["resets"] == 1 and any("160x120" in w for w in warned)
    c = cloud(got[0].msg)  # the new size's first frame is the new reference
    assert np.all(c["dx"][c["valid"] > 0] == 0) and c["x"].max() < 160
    # Stamps going back (a looped bag) reset too.
    p.process(message(frames[0], 0, "bgr8"))
    assert p.stats["resets"] == 2 and p.reference_stamp_ns == T0


def test_an_unreadable_encoding_is_one_line_naming_msg() -> None:
    t = store().types
    msg = t["sensor_msgs/msg/Image"](header=header(0), height=2, width=2, encoding="32FC1",
                                     is_bigendian=0, step=8, data=np.zeros(16, np.uint8))
    with pytest.raises(ValueError, match=r"^msg: Image encoding '32FC1'") as err:
        TactileProcessor().process(msg)
    assert "\n" not in str(err.value)


# --- parameters ----------------------------------------------------------------------------


@pytest.mark.parametrize(("params", "name"), [
    ({"motion": "flow"}, "motion"),
    ({"method": "magic"}, "method"),
    ({"reference": "last"}, "reference"),
    ({"reference_frame": 3}, "reference_frame"),
    ({"reference": "frame", "reference_frame": -1}, "reference_frame"),
    ({"look_ahead": 0}, "look_ahead"),
    ({"rest_frames": 0, "motion": "markerless"}, "rest_frames"),
    ({"rest_frames": 1.5, "motion": "markerless"}, "rest_frames"),
    ({"rest_frames": 16}, "rest_frames"),
    ({"rest_frames": 16, "motion": "markerless"}, "rest_frames"),
    ({"rule": "magic"}, "rule"),
    ({"score_threshold": 1.0, "rule": "paper"}, "score_threshold"),
    ({"score_threshold": float("inf")}, "score_threshold"),
    ({"threshold_px": 3.0}, "threshold_px"),
    ({"threshold_px": -1.0, "rule": "paper"}, "threshold_px"),
    ({"outputs": ["markerless", "pose"]}, "outputs"),
    ({"outputs": []}, "outputs"),
    ({"outputs": "slip"}, "outputs"),
    ({"device": "tpu"}, "device"),
    ({"colour": "red"}, "colour"),
])
def test_bad_parameters_are_one_line_naming_them(params: dict[str, Any], name: str) -> None:
    with pytest.raises(ValueError) as err:
        TactileProcessor(**params)
    text = str(err.value)
    assert text.startswith(f"{name}: ") and "\n" not in text


def test_config_defaults_match_the_node_parameters() -> None:
    from tacswitch.ros.node import PARAMETERS, processor_params

    cfg = ProcessorConfig(**processor_params(PARAMETERS))
    assert cfg == ProcessorConfig()
    assert {f.name for f in dataclasses.fields(ProcessorConfig)} == \
        set(PARAMETERS) - {"image_topic", "image_type"}


# --- the converter and the node without ROS -------------------------------------------------


def _rclpy_like(msgtype: str) -> type:
    """A stand-in for an rclpy message class: settable fields, the module rclpy uses."""
    pkg, _, name = msgtype.split("/")
    fields = [f.name for f in dataclasses.fields(store().types[msgtype])]

    def init(self: Any, **kw: Any) -> None:
        for f in fields:
            setattr(self, f, kw.get(f))

    return type(name, (), {"__module__": f"{pkg}.msg._{name.lower()}", "__init__": init,
                           "get_fields_and_field_types": lambda self: dict.fromkeys(fields)})


def test_converter_round_trips_the_node_messages() -> None:
    frames = grasp("slip")
    out = TactileProcessor(look_ahead=1).process(message(frames[0], 0, "bgr8"))
    assert {o.name for o in out} == {"markerless", "motion", "slip"}
    for o in out:
        ros = to_ros(o.msg, _rclpy_like)
        assert type(ros).__name__ == o.msgtype.split("/")[-1]
        assert isinstance(ros.data if hasattr(ros, "data") else array.array("B"), array.array)
        back = from_ros(ros, store())
        assert back.__msgtype__ == o.msgtype
        assert stamp(back) == T0
        if hasattr(back, "data"):
            np.testing.assert_array_equal(back.data, o.msg.data)
    # An incoming rclpy Image (data as array.array, as rclpy holds it) reaches the processor.
    img = to_ros(message(frames[0], 0, "rgb8"), _rclpy_like)
    got = TactileProcessor(look_ahead=1, outputs=["markerless"]).process(
        from_ros(img, store(), "sensor_msgs/msg/Image"))
    np.testing.assert_array_equal(got[0].msg.data.reshape(frames[0].shape),
                                  ts.remove_markers(decoded(frames[0], "rgb8")))


def test_node_module_imports_without_rclpy_and_main_says_what_to_install() -> None:
    code = ("import sys, tacswitch.ros.node as n; assert 'rclpy' not in sys.modules; "
            "sys.modules['rclpy'] = None; sys.exit(n.main([]))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60)
    assert run.returncode == 1
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tacswitch-ros-node: needs ROS 2's rclpy")
    assert 'pip install "tacswitch[ros]"' in lines[0] and "setup.bash" in lines[0]


def test_entry_point_and_launch_file_are_declared() -> None:
    import tomllib

    from tacswitch.ros.node import LAUNCH_FILE, PARAMETERS, main

    root = Path(__file__).resolve().parents[1]
    scripts = tomllib.loads((root / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["tacswitch-ros-node"] == "tacswitch.ros.node:main"
    assert LAUNCH_FILE.is_file()
    assert main(["--launch-file"]) == 0
    text = LAUNCH_FILE.read_text()
    for name in PARAMETERS:
        assert f'("{name}"' in text, name


@pytest.mark.parametrize(("dt_ns", "fps", "resampled"), [
    (10_000_000, None, 100.0),   # 100 frames/s from the stamps: resampled to the scorer's 25
    (DT, None, None),            # 30 frames/s: read frame by frame
    (10_000_000, 25.0, None),    # the parameter wins over the stamps
])
def test_the_learned_slip_reads_the_frame_rate_from_the_stamps(
        dt_ns: int, fps: float | None, resampled: float | None) -> None:
    t = store().types
    msgs = [message(f, 0, "bgr8") for f in grasp("hold")[:12]]
    for i, m in enumerate(msgs):
        ns = T0 + i * dt_ns
        m.header.stamp = t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)
    p = TactileProcessor(outputs=["slip"], fps=fps)
    assert len(by_name(process_all(p, msgs), "slip")) == len(msgs)
    tb = p.detector.timebase
    assert (tb is None) == (resampled is None)
    if resampled is not None:
        assert p.detector.fps == pytest.approx(resampled)
    with pytest.raises(ValueError, match="fps: applies to rule 'learned'"):
        TactileProcessor(outputs=["slip"], rule="paper", fps=60.0)
    with pytest.raises(ValueError, match="fps: must be a frame rate"):
        TactileProcessor(outputs=["slip"], fps=0.0)
