"""Record what the node publishes into a rosbag2 (MCAP storage, metadata version 9), and read
such bags back.

The writer registers exactly the topics and types of `topics.published_topics` and fills the
messages with `rft_sim_ros.ros.messages` through the rosbags backend, so a bag holds what the
rclpy node would have published. Timestamps are sim time in integer nanoseconds, the same
value as each message's stamp. No ROS installation is needed (rosbags is pure Python).
"""
import struct
from dataclasses import dataclass

from rosbags.rosbag2 import Reader, StoragePlugin, Writer

from rft_sim_ros.ros import cdr, messages, topics
from rft_sim_ros.ros.factory import RosbagsFactory, jazzy_typestore
from rft_sim_ros.ros.jazzy_types import typestore_for
from rft_sim_ros.stamps import seconds_to_ns, split_ns

#: The distribution whose message definitions the bags hold (metadata `ros_distro`).
ROS_DISTRO = 'jazzy'

#: An MCAP Message record's opcode, length and fixed fields: channel id (uint16), sequence
#: (uint32), log time and publish time (uint64 ns); the message data follows.
_MCAP_MESSAGE = struct.Struct('<BQHIQQ')
_MCAP_MESSAGE_FIELDS = _MCAP_MESSAGE.size - 9  # the record's length counts these
#: rosbags' McapWriter closes a chunk once it holds more than this many bytes.
_MCAP_CHUNK_SIZE = 2**20


class _CycleRecords:
    """A publish cycle of `encoder`'s topics (a `cdr.StateEncoder`) as the MCAP Message
    records of `connections` (one each, in topic order), packed by one struct call: each
    record's header (opcode, length, channel id, sequence 0 and the two times) then the
    message's CDR fields, whose layout is fixed for a run. starts, sizes: each record's
    offset in a cycle's bytes, and its message's CDR size; size: a cycle's bytes."""

    def __init__(self, encoder, connections):
        structs = encoder.structs
        self.sizes = [packer.size for packer in structs]
        self._prefixes = [struct.pack('<BQHI', 0x05, _MCAP_MESSAGE_FIELDS + size, c.id, 0)
                          for c, size in zip(connections, self.sizes)]
        self._struct = struct.Struct('<' + ''.join(
            f'{len(prefix)}sQQ' + packer.format.lstrip('<')
            for prefix, packer in zip(self._prefixes, structs)))
        self.starts = []
        offset = 0
        for size in self.sizes:
            self.starts.append(offset)
            offset += _MCAP_MESSAGE.size + size
        self.size = offset  # bytes of one cycle

    def pack(self, time_ns, arguments):
        """The cycle's bytes at `time_ns` (ns) from the encoder's `arguments`."""
        values = []
        for prefix, message in zip(self._prefixes, arguments):
            values += (prefix, time_ns, time_ns)
            values += message
        return self._struct.pack(*values)

    def payloads(self, data):
        """Each message's CDR bytes in a cycle's bytes `data`."""
        header = _MCAP_MESSAGE.size
        return [data[start + header:start + header + size]
                for start, size in zip(self.starts, self.sizes)]


class _Rosbag2Writer(Writer):
    """rosbags' Writer, with the ROS distribution of the messages (not 'rosbags') in the
    bag's metadata (metadata.yaml and the MCAP file's copy), and `write_cycle` /
    `write_records`: the messages of publish cycles written as batches."""

    def write_cycle(self, connections, time_ns, payloads):
        """Record CDR `payloads`, one per connection of `connections`, all at `time_ns`:
        the records `Writer.write` would append to the MCAP chunks, written together, with
        the same bookkeeping and chunk boundaries (the tests check the file is the same byte
        for byte)."""
        storage, counts, stats = self.storage, self.counts, self.storage.channel_stats
        pack = _MCAP_MESSAGE.pack
        chunk = None
        for connection, data in zip(connections, payloads):
            if chunk is None:
                chunk, parts = storage.chunk, []
                msgs, offset = chunk.msgs, chunk.bio.tell()
                chunk.message_start_time = min(time_ns, chunk.message_start_time)
                chunk.message_end_time = max(time_ns, chunk.message_end_time)
            cid, size = connection.id, len(data)
            parts += (pack(0x05, _MCAP_MESSAGE_FIELDS + size, cid, 0, time_ns, time_ns), data)
            msgs[cid].append((time_ns, offset))
            offset += _MCAP_MESSAGE.size + size
            stats[cid] += 1
            counts[cid] += 1
            if offset > _MCAP_CHUNK_SIZE:  # as Writer.write: close the chunk after this one
                chunk.bio.write(b''.join(parts))
                storage.close_chunk()
                chunk = None
        if chunk is not None:
            chunk.bio.write(b''.join(parts))
        self._cover(time_ns)

    def _cover(self, time_ns):
        """The storage's and the bag's time range extended to `time_ns` (as Writer.write)."""
        storage = self.storage
        storage.message_start_time = min(time_ns, storage.message_start_time)
        storage.message_end_time = max(time_ns, storage.message_end_time)
        self.min_timestamp = min(time_ns, self.min_timestamp)
        self.max_timestamp = max(time_ns, self.max_timestamp)

    def write_records(self, connections, cycles, records):
        """Record `cycles`, (time_ns, bytes) pairs in time order of `_CycleRecords.pack` of
        `records` for `connections`, as `write_cycle` would one by one (same bytes, same
        bookkeeping): the cycles that fit in the open chunk in one write, with their index
        entries added per channel at once; the cycle during which the chunk closes goes
        through `write_cycle`, message by message."""
        size = records.size
        while cycles:
            storage = self.storage
            chunk = storage.chunk
            offset = chunk.bio.tell()
            fit = min(len(cycles), (_MCAP_CHUNK_SIZE - offset) // size)
            if fit <= 0:  # the chunk closes within the next cycle
                time_ns, data = cycles[0]
                self.write_cycle(connections, time_ns, records.payloads(data))
                cycles = cycles[1:]
                continue
            written, cycles = cycles[:fit], cycles[fit:]
            chunk.bio.write(b''.join([data for _, data in written]))
            first, last = written[0][0], written[-1][0]
            chunk.message_start_time = min(first, chunk.message_start_time)
            chunk.message_end_time = max(last, chunk.message_end_time)
            msgs, stats, counts = chunk.msgs, storage.channel_stats, self.counts
            for connection, start in zip(connections, records.starts):
                cid = connection.id
                msgs[cid].extend([(time_ns, offset + start + k * size)
                                  for k, (time_ns, _) in enumerate(written)])
                stats[cid] += fit
                counts[cid] += fit
            self._cover(first)
            self._cover(last)

    def close(self):
        rosbags, ours = 'ros_distro: rosbags', f'ros_distro: {ROS_DISTRO}'
        close_storage = self.storage.close
        self.storage.close = lambda version, metadata: close_storage(
            version, metadata.replace(rosbags, ours))
        super().close()
        self.metapath.write_text(self.metapath.read_text().replace(rosbags, ours))


class BagWriter:
    """A rosbag2 folder at `path` (must not exist yet) recording the simulation's topics.

    leg_names: the scene's legs (one wrench topic each). plates: whether /rft/plates is
    recorded (as the node's parameter of the same meaning). terrain: whether /rft/terrain
    (PointCloud2) and /rft/terrain/marker (one MarkerArray a publication) are recorded
    (`write_terrain`). sensors: the run's `sensors.SensorLayout` (the states' sensor readings
    are recorded on its topics), or None. Use as a context manager or call `close()`; the bag
    is only complete once closed.
    """

    def __init__(self, path, leg_names, *, plates=False, terrain=False, sensors=None):
        self._plates = plates
        self._imu_topic = sensors.imu_topic if sensors is not None else topics.IMU
        self._types = topics.published_topics(leg_names, plates=plates, terrain=terrain,
                                              sensors=sensors)
        self.factory = RosbagsFactory(typestore_for(frozenset(self._types.values())))
        self._writer = _Rosbag2Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._connections = {
            topic: self._writer.add_connection(topic, msgtype, typestore=self.factory.typestore)
            for topic, msgtype in self._types.items()}
        self._encoder = None  # StateEncoder of the states' joints and legs
        self._encoded = []    # its topics' connections
        self._records = None  # _CycleRecords of those

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
        """Record one publishing cycle of `state` (`write_states`)."""
        self.write_states([state])

    def write_states(self, states):
        """Record the publishing cycles of `states` (SimStates, in time order): the messages
        of `messages.state_messages`, the fixed-layout ones packed directly
        (`cdr.StateEncoder`, same bytes) with their MCAP records in one struct call per cycle
        (`_CycleRecords`), and consecutive cycles written together."""
        batch = []
        for state in states:
            if self._encoder is None or not self._encoder.fits(state):
                self._write_cycles(batch)
                batch = []
                self._encoder = cdr.StateEncoder(state, self._imu_topic)
                unknown = sorted(set(self._encoder.topics) - set(self._connections))
                if unknown:
                    raise KeyError(f'{unknown} are not topics of this bag: '
                                   f'{sorted(self._types)}')
                self._encoded = [self._connections[topic] for topic in self._encoder.topics]
                self._records = _CycleRecords(self._encoder, self._encoded)
            time_ns = seconds_to_ns(state.time)
            arguments = self._encoder.arguments(state, *split_ns(time_ns))
            batch.append((time_ns, self._records.pack(time_ns, arguments)))
            if self._plates and state.active_plates is not None:
                self._write_cycles(batch)
                batch = []
                self.write(topics.PLATES, messages.plates_message(self.factory, state),
                           time_ns)
            if state.sensors is not None and state.sensors.model_sensors:
                self._write_cycles(batch)
                batch = []
                for topic, message in messages.model_sensor_messages(self.factory, state):
                    self.write(topic, message, time_ns)
        self._write_cycles(batch)

    def _write_cycles(self, cycles):
        if cycles:
            self._writer.write_records(self._encoded, cycles, self._records)

    def write_terrain(self, update):
        """Record a `terrain.TerrainUpdate` (`messages.terrain_messages`) at its sim time."""
        time_ns = seconds_to_ns(update.time)
        for topic, message in messages.terrain_messages(self.factory, update):
            self.write(topic, message, time_ns)

    def write_diagnostics(self, state, status):
        """Record /diagnostics for `state` and the run's `messages.RunStatus` (the bytes of
        `messages.diagnostics_message`, packed by `cdr.diagnostics`)."""
        time_ns = seconds_to_ns(state.time)
        self._writer.write_cycle([self._connections[topics.DIAGNOSTICS]], time_ns,
                                 [cdr.diagnostics(messages.diagnostic_fields(state, status),
                                                  *split_ns(time_ns))])

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
