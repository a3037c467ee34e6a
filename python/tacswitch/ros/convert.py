"""rclpy messages to and from the ``rosbags`` message dataclasses the processor works on.

The two have the same field names (both are generated from the same ``.msg`` definitions), so
a conversion is a walk over the fields: nested messages recursively, arrays of primitives as
numpy arrays (``rosbags``) or ``array.array`` (rclpy, whose generated setters take it without
checking every element), sequences of messages as lists. No rclpy import here: the node passes
rclpy's message class lookup (``rosidl_runtime_py.utilities.get_message``), and the tests pass
stand-ins.
"""

from __future__ import annotations

import array
import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

#: numpy dtype -> ``array.array`` typecode, for rclpy's primitive arrays.
_TYPECODES = {"uint8": "B", "int8": "b", "uint16": "H", "int16": "h", "uint32": "I",
              "int32": "i", "uint64": "Q", "int64": "q", "float32": "f", "float64": "d"}


def ros_type_name(msg: Any) -> str:
    """``pkg/msg/Name`` of an rclpy message (its class lives in ``pkg.msg._name``)."""
    cls = type(msg)
    return f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"


def _is_message(value: Any) -> bool:
    return hasattr(value, "get_fields_and_field_types")


def from_ros(msg: Any, store: Any, msgtype: str | None = None) -> Any:
    """An rclpy message as the ``rosbags`` dataclass of the type store ``store``.

    Args:
        msg: an rclpy message (anything with ``get_fields_and_field_types()``).
        store: a ``rosbags`` type store (``get_typestore(Stores.ROS2_HUMBLE)``).
        msgtype: ``pkg/msg/Name`` (default: from the message's class).
    """
    cls = store.types[msgtype or ros_type_name(msg)]
    kwargs = {}
    for f in dataclasses.fields(cls):
        kwargs[f.name] = _from_value(getattr(msg, f.name), store)
    return cls(**kwargs)


def _from_value(value: Any, store: Any) -> Any:
    if _is_message(value):
        return from_ros(value, store)
    if isinstance(value, (bytes, bytearray, memoryview)):
        return np.frombuffer(bytes(value), np.uint8)
    if isinstance(value, array.array):
        return np.frombuffer(value.tobytes(), np.dtype(value.typecode))
    if isinstance(value, np.ndarray):
        return value
    if isinstance(value, (list, tuple)):
        if value and _is_message(value[0]):
            return [from_ros(v, store) for v in value]
        return list(value)
    return value


def to_ros(msg: Any, get_message: Callable[[str], type]) -> Any:
    """A ``rosbags`` message dataclass as an rclpy message.

    Args:
        msg: a ``rosbags`` message dataclass (it names its type in ``__msgtype__``).
        get_message: ``pkg/msg/Name`` -> the rclpy message class
            (``rosidl_runtime_py.utilities.get_message``).
    """
    out = get_message(msg.__msgtype__)()
    for f in dataclasses.fields(msg):
        setattr(out, f.name, _to_value(getattr(msg, f.name), get_message))
    return out


def _to_value(value: Any, get_message: Callable[[str], type]) -> Any:
    if hasattr(value, "__msgtype__") and dataclasses.is_dataclass(value):
        return to_ros(value, get_message)
    if isinstance(value, np.ndarray):
        code = _TYPECODES.get(value.dtype.name)
        if code is None:
            return value.tolist()
        return array.array(code, np.ascontiguousarray(value).tobytes())
    if isinstance(value, list):
        return [_to_value(v, get_message) for v in value]
    if isinstance(value, np.generic):  # rclpy's setters want Python numbers
        return value.item()
    return value
