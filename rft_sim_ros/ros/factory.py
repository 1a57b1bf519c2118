"""Message factories: one interface, two backends (rosbags dataclasses, rclpy classes).

`rft_sim_ros.ros.messages` fills messages only through a factory, so the same code produces
what the rclpy node publishes and what the rosbag2 writer records. Type names use the
rosbags/IDL spelling 'package/msg/Name'. Scalars are passed as plain Python int/float/str;
the factory converts only the field kinds whose Python form differs between backends:

=================  ==========================  =====================================
field kind         rosbags backend             rclpy backend
=================  ==========================  =====================================
float64[]          numpy float64 array         array.array('d')
float64[N]         numpy float64 array (N,)    numpy float64 array (N,)
uint8[]            numpy uint8 array           array.array('B')
byte               int                         bytes of length 1
=================  ==========================  =====================================
"""
import array
import functools
import importlib
from typing import Any, Protocol

import numpy as np

#: The messages of an action that rclpy nests in its class (`Action.Goal`), by the suffix
#: the rosbags/IDL spelling gives them ('pkg/action/Action_Goal').
ACTION_PARTS = ('Goal', 'Result', 'Feedback')


class MessageFactory(Protocol):
    """What `rft_sim_ros.ros.messages` needs from a message backend."""

    def make(self, type_name: str, **fields: Any) -> Any:
        """A message of `type_name` ('pkg/msg/Name') with the given fields."""

    def float64_sequence(self, values) -> Any:
        """Value for a float64[] field."""

    def float64_array(self, values, size: int) -> Any:
        """Value for a float64[size] field; raises ValueError on a wrong size."""

    def uint8_sequence(self, values) -> Any:
        """Value for a uint8[] field."""

    def byte(self, value: int) -> Any:
        """Value for a byte field (0..255)."""


def _fixed_float64(values, size):
    out = np.array(values, dtype=np.float64).reshape(-1)
    if out.size != size:
        raise ValueError(f'float64[{size}] field needs {size} values, got {out.size}')
    return out


@functools.lru_cache(maxsize=None)
def jazzy_typestore():
    """The rosbags typestore holding the ROS 2 Jazzy message definitions (built once)."""
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


class RosbagsFactory:
    """Builds rosbags message dataclasses (every field is required, so none can be forgotten).

    The result serialises with `typestore.serialize_cdr(msg, msg.__msgtype__)`.
    """

    def __init__(self, typestore=None):
        self.typestore = typestore if typestore is not None else jazzy_typestore()

    def make(self, type_name, **fields):
        return self.typestore.types[type_name](**fields)

    def float64_sequence(self, values):
        return np.array(values, dtype=np.float64).reshape(-1)

    def float64_array(self, values, size):
        return _fixed_float64(values, size)

    def uint8_sequence(self, values):
        return np.array(values, dtype=np.uint8).reshape(-1)

    def byte(self, value):
        return int(value)


class RclpyFactory:
    """Builds rclpy message objects; message packages are imported on first use.

    Only usable where ROS 2 is sourced. Classes are looked up as `pkg.msg.Name`.
    """

    def __init__(self):
        self._classes = {}

    def message_class(self, type_name):
        """The rclpy class of `type_name`: 'pkg/msg/Name', 'pkg/srv/Name', 'pkg/action/Name',
        or an action's part 'pkg/action/Name_Goal' (_Result, _Feedback), which rclpy nests
        as Name.Goal."""
        cls = self._classes.get(type_name)
        if cls is None:
            package, kind, name = type_name.split('/')
            action, _, part = name.rpartition('_')
            nested = kind == 'action' and part in ACTION_PARTS
            cls = getattr(importlib.import_module(f'{package}.{kind}'),
                          action if nested else name)
            if nested:
                cls = getattr(cls, part)
            self._classes[type_name] = cls
        return cls

    def make(self, type_name, **fields):
        return self.message_class(type_name)(**fields)

    def float64_sequence(self, values):
        return array.array('d', np.ascontiguousarray(values, dtype=np.float64).tobytes())

    def float64_array(self, values, size):
        return _fixed_float64(values, size)

    def uint8_sequence(self, values):
        return array.array('B', np.ascontiguousarray(values, dtype=np.uint8).tobytes())

    def byte(self, value):
        return bytes([value])
