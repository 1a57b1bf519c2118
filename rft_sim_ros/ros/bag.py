"""Record what the node publishes into a rosbag2 (MCAP storage, metadata version 9), and read
such bags back.

The writer registers exactly the topics and types of `topics.published_topics` and fills the
messages with `rft_sim_ros.ros.messages` through the rosbags backend, so a bag holds what the
rclpy node would have published. Timestamps are sim time in integer nanoseconds, the same
value as each message's stamp. No ROS installation is needed (rosbags is pure Python).
"""
from dataclasses import dataclass

from rosbags.rosbag2 import Reader, StoragePlugin, Writer

from rft_sim_ros.ros import messages, topics
from rft_sim_ros.ros.factory import RosbagsFactory, jazzy_typestore
from rft_sim_ros.ros.stamps import seconds_to_ns


class BagWriter:
    """A rosbag2 folder at `path` (must not exist yet) recording the simulation's topics.

    leg_names: the scene's legs (one wrench topic each). plates: whether /rft/plates is
    recorded (as the node's parameter of the same meaning). Use as a context manager or call
    `close()`; the bag is only complete once closed.
    """

    def __init__(self, path, leg_names, *, plates=False):
        self.factory = RosbagsFactory(jazzy_typestore())
        self._plates = plates
        self._types = topics.published_topics(leg_names, plates=plates)
        self._writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._connections = {
            topic: self._writer.add_connection(topic, msgtype, typestore=self.factory.typestore)
            for topic, msgtype in self._types.items()}

    def write(self, topic, message, time_ns):
        """Record `message` (a rosbags message of the topic's type) at `time_ns` (ns)."""
        expected = self._types.get(topic)
        if expected is None:
            raise KeyError(f'{topic} is not a topic of this bag: {sorted(self._types)}')
        if message.__msgtype__ != expected:
            raise TypeError(f'{topic} carries {expected}, got {message.__msgtype__}')
        data = self.factory.typestore.serialize_cdr(message, expected)
        self._writer.write(self._connections[topic], time_ns, data)

    def write_state(self, state):
        """Record one publishing cycle of `state` (see `messages.state_messages`)."""
        time_ns = seconds_to_ns(state.time)
        for topic, message in messages.state_messages(self.factory, state, plates=self._plates):
            self.write(topic, message, time_ns)

    def write_diagnostics(self, state, status):
        """Record /diagnostics for `state` and the run's `messages.RunStatus`."""
        self.write(topics.DIAGNOSTICS, messages.diagnostics_message(self.factory, state, status),
                   seconds_to_ns(state.time))

    def close(self):
        """Finish the bag (writes the MCAP summary and metadata.yaml)."""
        self._writer.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()


@dataclass(frozen=True)
class TopicInfo:
    """A recorded topic: its message type and number of messages."""
    msgtype: str
    count: int


def bag_topics(path):
    """{topic: TopicInfo} of the rosbag2 folder at `path`."""
    with Reader(path) as reader:
        return {topic: TopicInfo(info.msgtype, info.msgcount)
                for topic, info in reader.topics.items()}


def read_messages(path, topic_names=None):
    """Yield (topic, timestamp in ns, deserialised rosbags message) in timestamp order.

    topic_names: only these topics (default: all).
    """
    typestore = jazzy_typestore()
    with Reader(path) as reader:
        connections = [c for c in reader.connections
                       if topic_names is None or c.topic in topic_names]
        if not connections:
            return
        for connection, time_ns, data in reader.messages(connections=connections):
            yield connection.topic, time_ns, typestore.deserialize_cdr(data, connection.msgtype)
