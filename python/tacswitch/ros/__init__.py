"""A live ROS 2 node for tacswitch (``tacswitch-ros-node``, docs/ros.md "Live node").

- :mod:`tacswitch.ros.processor`: :class:`~tacswitch.ros.processor.TactileProcessor`, one image
  message in, the result messages out (``rosbags`` message dataclasses); no ROS needed.
- :mod:`tacswitch.ros.convert`: rclpy messages to and from ``rosbags`` dataclasses.
- :mod:`tacswitch.ros.node`: the rclpy node, a thin shell over the processor; the only module
  that imports ``rclpy`` (inside its functions).

Nothing here is imported by ``import tacswitch``.
"""
