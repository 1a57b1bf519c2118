"""CDR bytes of the state topics, packed straight from a `SimState`: the bag's fast path.

A headless run records about ten messages per publish cycle. Building rosbags message objects
(`messages.state_messages`) and serialising them cost about 30 us a message, a third of a
hexapod run. But the state topics have layouts that are fixed for a run (frame ids, joint
and leg names do not change), so each is one precompiled `struct.Struct`: alignment padding
in the format, the constant strings as prepacked bytes, the numbers as its values. The bag
writer joins a cycle's formats, with their MCAP record headers, into one struct and packs a
whole cycle in one call (`bag._CycleRecords`).

The bytes are what rosbags' (and rclpy's) serialiser writes for the messages
`rft_sim_ros.ros.messages` builds from the same state: little-endian plain CDR (XCDR1) with
its 4-byte encapsulation header, alignment counted from after that header. The tests check
this byte for byte. /diagnostics (strings of varying length) is written by `diagnostics`
(rosbags builds a type's serialiser on its first use, 20 ms); /rft/plates keeps the message
path.
"""
import struct

from rft_sim_ros.ros import topics

_ENCAPSULATION = b'\x00\x01\x00\x00'  # CDR_LE, options 0


class _Layout:
    """Builds a struct format over a CDR body: numbers aligned to their size, constants as
    prepacked bytes (their own padding included) passed as 's' arguments."""

    def __init__(self):
        self._format = ['<4s']
        self._offset = 0  # bytes after the encapsulation header

    def _align(self, size):
        pad = -self._offset % size
        if pad:
            self._format.append(f'{pad}x')
            self._offset += pad

    def numbers(self, code, count=1):
        """`count` numbers of struct code `code` ('i', 'I', 'd'), aligned to their size."""
        size = struct.calcsize(code)
        self._align(size)
        self._format.append(f'{count}{code}')
        self._offset += size * count

    def zeros(self, code, count):
        """`count` numbers of code `code` that are always zero (padding bytes)."""
        size = struct.calcsize(code)
        self._align(size)
        self._format.append(f'{size * count}x')
        self._offset += size * count

    def strings(self, texts, sequence=False):
        """Constant strings (a string[] with its length if `sequence`); returns their bytes,
        one argument of the format."""
        self._align(4)
        start = self._offset
        blob = bytearray(struct.pack('<I', len(texts)) if sequence else b'')
        for text in texts:
            blob += b'\x00' * (-(start + len(blob)) % 4)
            data = text.encode() + b'\x00'
            blob += struct.pack('<I', len(data)) + data
        self._format.append(f'{len(blob)}s')
        self._offset += len(blob)
        return bytes(blob)

    def float64_sequence(self, count):
        """A float64[] of `count` values: its length, then the values (`numbers`; none, and
        no alignment, when empty: CDR aligns elements); returns the length's bytes, one
        argument."""
        length = self.constant(struct.pack('<I', count))
        if count:
            self.numbers('d', count)
        return length

    def constant(self, data):
        """Constant bytes `data` (4-aligned); returns them, one argument."""
        self._align(4)
        self._format.append(f'{len(data)}s')
        self._offset += len(data)
        return data

    def compile(self):
        return struct.Struct(''.join(self._format))


def _header(layout, frame_id):
    layout.numbers('i')
    layout.numbers('I')
    return layout.strings([frame_id])


def _sensor_shape(state):
    """(IMU frame or None, contact legs or None) of a state's sensor readings."""
    readings = state.sensors
    if readings is None:
        return None, None
    return (readings.imu.frame if readings.imu is not None else None,
            readings.contacts.legs if readings.contacts is not None else None)


class StateEncoder:
    """The CDR layouts (`structs`) and values (`arguments`) of one publish cycle's
    fixed-layout topics, for states with the joints, legs and sensors of `state` (a
    SimState): /clock, /joint_states, /odom, /tf, /rft/<leg>/wrench, and where the state
    carries them the IMU (on `imu_topic`) and /rft/foot_contacts."""

    def __init__(self, state, imu_topic=topics.IMU):
        self.joint_names = tuple(state.joint_names)
        self.leg_names = tuple(leg.name for leg in state.legs)
        self.base_frame = state.base_frame
        self.sensor_shape = _sensor_shape(state)
        imu_frame, contact_legs = self.sensor_shape
        self.topics = [topics.CLOCK, topics.JOINT_STATES, topics.ODOM, topics.TF,
                       *(topics.leg_wrench_topic(name) for name in self.leg_names),
                       *([imu_topic] if imu_frame is not None else []),
                       *([topics.FOOT_CONTACTS] if contact_legs is not None else [])]

        layout = _Layout()
        layout.numbers('i')
        layout.numbers('I')
        self._clock = layout.compile()

        layout = _Layout()
        self._joint_frame = _header(layout, '')
        self._joint_names = layout.strings(self.joint_names, sequence=True)
        joints = len(self.joint_names)
        self._joint_count = [layout.float64_sequence(joints) for _ in range(3)]
        self._joint_state = layout.compile()

        layout = _Layout()
        self._odom_frames = (_header(layout, topics.ODOM_FRAME),
                             layout.strings([self.base_frame]))
        layout.numbers('d', 7)
        layout.zeros('d', 36)
        layout.numbers('d', 6)
        layout.zeros('d', 36)
        self._odom = layout.compile()

        layout = _Layout()
        self._tf_count = layout.constant(struct.pack('<I', 1 + len(self.leg_names)))
        self._tf_frames = []
        for child in (self.base_frame, *map(topics.leg_frame_id, self.leg_names)):
            self._tf_frames.append((_header(layout, topics.ODOM_FRAME),
                                    layout.strings([child])))
            layout.numbers('d', 7)
        self._tf = layout.compile()

        self._wrenches = []  # per leg: (its struct, its frame id's bytes)
        for name in self.leg_names:
            layout = _Layout()
            frame = _header(layout, topics.leg_frame_id(name))
            layout.numbers('d', 6)
            self._wrenches.append((layout.compile(), frame))

        self._sensors = []  # (its struct, its constant arguments' bytes) of each
        if imu_frame is not None:
            layout = _Layout()
            frame = _header(layout, imu_frame)
            layout.numbers('d', 4 + 9 + 3 + 9 + 3 + 9)
            self._sensors.append((layout.compile(), (frame,)))
        if contact_legs is not None:
            layout = _Layout()
            frame = _header(layout, '')
            names = layout.strings(contact_legs, sequence=True)
            counts = (layout.float64_sequence(len(contact_legs)), layout.float64_sequence(0),
                      layout.float64_sequence(len(contact_legs)))
            self._sensors.append((layout.compile(), (frame, names, *counts)))

    def fits(self, state):
        """Whether `state` has the joints, legs and base frame this encoder was built for."""
        return (tuple(state.joint_names) == self.joint_names
                and tuple(leg.name for leg in state.legs) == self.leg_names
                and state.base_frame == self.base_frame
                and _sensor_shape(state) == self.sensor_shape)

    @property
    def structs(self):
        """The `struct.Struct` of each message of `self.topics`, in that order (formats
        little-endian with no implicit alignment, so they may be concatenated)."""
        return [self._clock, self._joint_state, self._odom, self._tf,
                *(wrench for wrench, _ in self._wrenches),
                *(sensor for sensor, _ in self._sensors)]

    def arguments(self, state, sec, nanosec):
        """The values of each message's struct (`structs`), in topic order, for `state`
        stamped (sec, nanosec) (its sim time): a list of lists."""
        e = _ENCAPSULATION
        x, y, z = state.base_position.tolist()
        qw, qx, qy, qz = state.base_quaternion_wxyz.tolist()
        count = self._joint_count
        out = [[e, sec, nanosec],
               [e, sec, nanosec, self._joint_frame, self._joint_names,
                count[0], *state.joint_positions.tolist(),
                count[1], *state.joint_velocities.tolist(),
                count[2], *state.joint_efforts.tolist()],
               [e, sec, nanosec, *self._odom_frames, x, y, z, qx, qy, qz, qw,
                *state.base_linear_velocity.tolist(), *state.base_angular_velocity.tolist()]]
        frames = self._tf_frames
        transforms = [e, self._tf_count, sec, nanosec, *frames[0], x, y, z, qx, qy, qz, qw]
        for leg, frame in zip(state.legs, frames[1:]):
            transforms += [sec, nanosec, *frame, *leg.point.tolist(), 0.0, 0.0, 0.0, 1.0]
        out.append(transforms)
        for leg, (_, frame) in zip(state.legs, self._wrenches):
            out.append([e, sec, nanosec, frame, *leg.force.tolist(), *leg.torque.tolist()])
        if self._sensors:
            out += self._sensor_arguments(state, sec, nanosec)
        return out

    def _sensor_arguments(self, state, sec, nanosec):
        e, readings, out = _ENCAPSULATION, state.sensors, []
        parts = iter(self._sensors)
        imu = readings.imu
        if imu is not None:
            w, x, y, z = imu.quaternion_wxyz.tolist()
            out.append([e, sec, nanosec, *next(parts)[1], x, y, z, w,
                        *imu.orientation_covariance.tolist(), *imu.angular_velocity.tolist(),
                        *imu.angular_velocity_covariance.tolist(),
                        *imu.linear_acceleration.tolist(),
                        *imu.linear_acceleration_covariance.tolist()])
        contacts = readings.contacts
        if contacts is not None:
            frame, names, positions, velocities, efforts = next(parts)[1]
            out.append([e, sec, nanosec, frame, names, positions,
                        *contacts.stance.astype(float).tolist(), velocities, efforts,
                        *contacts.normal_force.tolist()])
        return out


def _uint32(buffer, value):
    """Append a 4-aligned uint32 to `buffer` (its offsets count from after the encapsulation
    header)."""
    buffer += b'\x00' * (-(len(buffer) - 4) % 4) + struct.pack('<I', value)


def _string(buffer, text):
    """Append a CDR string (uint32 length with the NUL, bytes, NUL) to `buffer`."""
    data = text.encode() + b'\x00'
    _uint32(buffer, len(data))
    buffer += data


def diagnostics(fields, sec, nanosec):
    """CDR bytes of /diagnostics (diagnostic_msgs/DiagnosticArray, one status) holding
    `fields` (messages.DiagnosticFields), stamped (sec, nanosec)."""
    buffer = bytearray(_ENCAPSULATION + struct.pack('<iI', sec, nanosec))
    _string(buffer, '')                                   # header.frame_id
    _uint32(buffer, 1)                                    # one status
    buffer.append(fields.level)                           # its level (byte)
    for text in (fields.name, fields.message, fields.hardware_id):
        _string(buffer, text)
    _uint32(buffer, len(fields.values))
    for key, value in fields.values:
        _string(buffer, key)
        _string(buffer, value)
    return bytes(buffer)
