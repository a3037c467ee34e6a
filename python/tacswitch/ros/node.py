"""``tacswitch-ros-node``: the live ROS 2 node, a thin shell over
:class:`tacswitch.ros.processor.TactileProcessor` (docs/ros.md, "Live node").

Subscribes to ``image_topic`` (``sensor_msgs/Image``, or ``sensor_msgs/CompressedImage`` with
``image_type:=compressed``), converts each message to the ``rosbags`` dataclass the processor
takes (:mod:`tacswitch.ros.convert`), and publishes what it returns on
``<image_topic>/markerless``, ``<image_topic>/marker_motion`` and ``<image_topic>/slip`` (the
topics and messages ``--out-bag`` writes), with the input's header. The service
``~/recapture`` (``std_srvs/Trigger``) makes the next frame the reference.

This is the only tacswitch module that imports ``rclpy``, and only inside its functions:
importing it never needs ROS; running :func:`main` without ``rclpy`` prints one line saying
what to install.

Not run against ROS 2 here: ROS 2 cannot be installed on the development machine; the
processor is tested with the real ROS 2 message types of ``rosbags``
(``tests/test_ros_processor.py``).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any

PROG = "tacswitch-ros-node"
#: The launch file shipped with the package (``ros2 launch`` takes its path).
LAUNCH_FILE = Path(__file__).resolve().parent / "launch" / "tacswitch.launch.py"
MISSING_RCLPY = (f"{PROG}: needs ROS 2's rclpy, which is not importable here: source your ROS 2 "
                 "setup (source /opt/ros/<distro>/setup.bash) and pip install "
                 "\"tacswitch[ros]\" into that Python")
USAGE = (f"usage: {PROG} [--launch-file] [--ros-args -p NAME:=VALUE ...]: the tacswitch ROS 2 "
         "node (parameters: docs/ros.md, \"Live node\"); --launch-file prints the path of the "
         "shipped launch file")

#: The node's ROS parameters and their defaults (the processor's, plus the subscription's).
#: A NaN threshold means "the default" (a ROS parameter cannot be unset).
PARAMETERS: dict[str, Any] = {
    "image_topic": "/tactile/image_raw",
    "image_type": "image",
    "motion": "markers",
    "method": "telea",
    "anchor": "auto",
    "rest_frames": 1,
    "reference": "first",
    "reference_frame": 0,
    "look_ahead": 30,
    "rule": "learned",
    "score_threshold": math.nan,
    "fps": math.nan,
    "threshold_px": math.nan,
    "outputs": ["markerless", "motion", "slip"],
    "device": "auto",
}
IMAGE_TYPES = {"image": "sensor_msgs/msg/Image",
               "compressed": "sensor_msgs/msg/CompressedImage"}


def processor_params(values: dict[str, Any]) -> dict[str, Any]:
    """The processor's keyword parameters from the node's parameter values (NaN thresholds:
    None; the subscription's own parameters left out)."""
    out = {k: v for k, v in values.items() if k not in ("image_topic", "image_type")}
    for k in ("score_threshold", "fps", "threshold_px"):
        v = out.get(k)
        if isinstance(v, float) and math.isnan(v):
            out[k] = None
    if "outputs" in out:
        out["outputs"] = tuple(out["outputs"])
    return out


def _image_type(value: Any) -> str:
    if value not in IMAGE_TYPES:
        raise ValueError(f"image_type: one of {', '.join(IMAGE_TYPES)}; got {value!r}")
    return IMAGE_TYPES[value]


def _make_node() -> Any:
    """The rclpy node class (defined here: rclpy is imported only when the node runs)."""
    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data
    from rosidl_runtime_py.utilities import get_message
    from std_srvs.srv import Trigger

    from tacswitch.ros.convert import from_ros, to_ros
    from tacswitch.ros.processor import TactileProcessor

    class TacswitchNode(Node):  # type: ignore[misc]
        def __init__(self) -> None:
            super().__init__("tacswitch")
            values = {k: self.declare_parameter(k, v).value for k, v in PARAMETERS.items()}
            self.msgtype = _image_type(values["image_type"])
            logger = self.get_logger()
            self.processor = TactileProcessor(warn=logger.warning,
                                              **processor_params(values))
            topic = str(values["image_topic"]).rstrip("/")
            self.publishers_: dict[str, Any] = {}
            for out in self.processor.config.outputs:
                suffix, msgtype = {"markerless": ("markerless", "sensor_msgs/msg/Image"),
                                   "motion": ("marker_motion", "sensor_msgs/msg/PointCloud2"),
                                   "slip": ("slip", "diagnostic_msgs/msg/DiagnosticArray"),
                                   }[out]
                self.publishers_[suffix] = self.create_publisher(
                    get_message(msgtype), f"{topic}/{suffix}", 10)
            self.get_message = get_message
            self.store = self.processor.store
            self.errors: set[str] = set()
            # Sensor-data QoS (best effort, keep last 5): matches reliable and best-effort
            # camera publishers; a slow frame drops the oldest instead of queueing latency.
            self.create_subscription(get_message(self.msgtype), topic, self.on_image,
                                     qos_profile_sensor_data)
            self.create_service(Trigger, "~/recapture", self.on_recapture)
            logger.info(f"tacswitch: {topic} ({self.msgtype}) -> "
                        f"{', '.join(f'{topic}/{s}' for s in self.publishers_)}")

        def on_image(self, msg: Any) -> None:
            try:
                outputs = self.processor.process(from_ros(msg, self.store, self.msgtype),
                                                 self.msgtype)
            except ValueError as exc:  # an encoding tacswitch does not read: say it once
                if str(exc) not in self.errors:
                    self.errors.add(str(exc))
                    self.get_logger().error(f"tacswitch: {exc}")
                return
            for out in outputs:
                self.publishers_[out.suffix].publish(to_ros(out.msg, self.get_message))

        def on_recapture(self, request: Any, response: Any) -> Any:
            self.processor.recapture()
            response.success = True
            response.message = "the next frame is the reference"
            return response

    return TacswitchNode


def main(argv: list[str] | None = None) -> int:
    """Runs the node until interrupted; the console script ``tacswitch-ros-node``.

    Returns 0, 1 when ROS 2 or ``rosbags`` is missing (one line on stderr saying what to
    install), 2 for a bad parameter (one line naming it).
    """
    args = sys.argv[1:] if argv is None else list(argv)
    own = args[:args.index("--ros-args")] if "--ros-args" in args else args
    if "-h" in own or "--help" in own:
        print(USAGE)
        return 0
    if "--launch-file" in own:
        print(LAUNCH_FILE)
        return 0
    try:
        import rclpy
    except ImportError:
        print(MISSING_RCLPY, file=sys.stderr)
        return 1
    rclpy.init(args=[sys.argv[0], *args])
    node = None
    try:
        node = _make_node()()
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    except ImportError as exc:
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 1
    except ValueError as exc:  # a bad parameter: one line naming it
        print(f"{PROG}: {exc}", file=sys.stderr)
        return 2
    finally:
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
