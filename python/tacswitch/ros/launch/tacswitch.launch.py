"""Launches ``tacswitch-ros-node`` with its parameters (docs/ros.md, "Live node").

    ros2 launch $(tacswitch-ros-node --launch-file) image_topic:=/gelsight/image_raw

Every parameter is a launch argument of the same name; the node's executable is the console
script ``tacswitch-ros-node`` found on PATH (pip install "tacswitch[ros]" into the ROS 2 Python
environment), so no colcon package is needed.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

# name, default, type, description (the processor's defaults; docs/ros.md has the table).
ARGUMENTS = [
    ("image_topic", "/tactile/image_raw", str, "tactile image topic"),
    ("image_type", "image", str, "image (sensor_msgs/Image) or compressed (CompressedImage)"),
    ("motion", "markers", str, "markers (tracked) or markerless (a markerless sensor)"),
    ("method", "telea", str, "marker removal: telea, biharmonic, ns, tacdiff, hybrid"),
    ("anchor", "auto", str, "markerless motion: auto, contact or rest (MarkerlessTracker)"),
    ("rest_frames", "1", int, "markerless motion: frames the reference may average (1: as is)"),
    ("reference", "first", str, "reference frame: first, frame, service"),
    ("reference_frame", "0", int, "reference:=frame: the readable frame (0-based)"),
    ("look_ahead", "30", int, "reference:=first: frames held to choose it"),
    ("rule", "learned", str, "slip rule: learned or paper"),
    ("score_threshold", ".nan", float, "learned rule: logit threshold (.nan: the model's)"),
    ("fps", ".nan", float, "learned rule: camera frames/s (.nan: from the stamps)"),
    ("threshold_px", ".nan", float, "paper rule: displacement threshold, px (.nan: default)"),
    ("outputs", "[markerless, motion, slip]", list, "results to publish"),
    ("device", "auto", str, "auto, cpu or cuda (tacdiff, hybrid)"),
]


def generate_launch_description() -> LaunchDescription:
    declared = [DeclareLaunchArgument(name, default_value=default, description=text)
                for name, default, _, text in ARGUMENTS]
    # str values stay strings; the others are read as YAML (numbers, .nan, a list).
    params = {name: ParameterValue(LaunchConfiguration(name),
                                   value_type=str if kind is str else None)
              for name, _, kind, _ in ARGUMENTS}
    node = Node(executable="tacswitch-ros-node", name="tacswitch", output="screen",
                parameters=[params])
    return LaunchDescription([*declared, node])
