"""Fill the ROS 2 messages the simulation publishes from a `SimState`.

ROS-free: every message is built through a message factory (`rft_sim_ros.ros.factory`), so
the same functions fill rclpy messages in the node and rosbags messages in the bag writer.
Every field of every message is set explicitly. Units are SI (REP 103); every stamp is the
state's sim time.

Frames (REP 105, names in `rft_sim_ros.ros.topics`):
  odom       fixed world frame of the simulation, z up (the MuJoCo world frame).
  base       the robot's base body, named as in the model (a URDF's root link:
             base_link, base, ...); /odom and /tf carry odom -> base.
  rft/<leg>  one per leg: child of odom, origin at the leg's reference point
             (`LegWrench.point`), axes parallel to odom (identity rotation). The leg's
             wrench is published in this frame, so force.z is the vertical ground force in
             world axes and the torque is taken about the leg's reference point.

Covariance convention: /odom is ground truth taken from the simulator, so every pose and
twist covariance entry is 0 (exact). It is not "unknown" (that would be -1 in element 0).
"""
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from rft_sim_ros.ros import topics
from rft_sim_ros.ros.diagnostics import outcome_values
from rft_sim_ros.sim.ways_down import is_down
from rft_sim_ros.stamps import seconds_to_ns, split_ns
from rft_sim_ros.units import zeta_to_si

#: Pose and twist covariance of /odom (row-major 6x6, all zero: exact ground truth).
ODOM_COVARIANCE = np.zeros(36)

#: Plate stress shown full red: the stress of a plate pushed straight down this deep (m),
#: i.e. zeta * depth. Lower stresses fade linearly to blue.
PLATE_STRESS_FULL_SCALE_DEPTH_M = 0.05

#: Marker namespace and id of the active-plates marker on /rft/plates.
PLATES_MARKER_NS = 'rft_plates'
PLATES_MARKER_ID = 0

#: Marker namespace of the deformed-sand markers in the MarkerArrays on /rft/terrain/marker
#: (one per tile, the tile's index as id: `terrain.TerrainTile`).
TERRAIN_MARKER_NS = 'rft_terrain'
#: Height change shown full blue (dug) or full red (piled), m.
TERRAIN_CHANGE_FULL_SCALE_M = 0.02
#: sensor_msgs/PointField datatype of float32.
POINT_FIELD_FLOAT32 = 7

_IDENTITY_WXYZ = (1.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ServiceResult:
    """Answer of a service: std_srvs' `success` and `message`."""
    success: bool
    message: str


@dataclass(frozen=True)
class RunStatus:
    """Run-level values reported on /diagnostics that a `SimState` does not carry.

    scene: scene name (DiagnosticStatus.hardware_id).
    real_time_factor: sim seconds per wall second, as measured by the caller
        (nan until measured).
    stable: False once the run has diverged; `problem` then says why.
    commands_rejected: count of rejected commands per reason
        (`CommandHandler.rejections`).
    paused: True while the simulation is paused (sim time stands still).
    outcome: the run's outcome so far (`Simulation.outcome`; None: not given).
    kernels: which sand kernels run, the prebuilt ones or numba's, and which prebuilt kernels
        were given other types, so that numba's ran them (`Simulation.kernels`), beside the
        real-time factor they give ('': not said).
    """
    scene: str
    real_time_factor: float
    stable: bool = True
    problem: str = ''
    commands_rejected: Mapping[str, int] = field(default_factory=dict)
    paused: bool = False
    outcome: Mapping = None
    kernels: str = ''


def stamp(factory, t):
    """builtin_interfaces/Time of sim time `t` (s), rounded to the nearest nanosecond."""
    sec, nanosec = split_ns(seconds_to_ns(t))
    return factory.make('builtin_interfaces/msg/Time', sec=sec, nanosec=nanosec)


def header(factory, t, frame_id):
    """std_msgs/Header stamped with sim time `t` (s) in frame `frame_id`."""
    return factory.make('std_msgs/msg/Header', stamp=stamp(factory, t), frame_id=frame_id)


def _vector3(factory, v):
    return factory.make('geometry_msgs/msg/Vector3', x=float(v[0]), y=float(v[1]),
                        z=float(v[2]))


def _point(factory, p):
    return factory.make('geometry_msgs/msg/Point', x=float(p[0]), y=float(p[1]),
                        z=float(p[2]))


def _quaternion(factory, wxyz):
    """geometry_msgs/Quaternion (x, y, z, w) from a MuJoCo-order (w, x, y, z) quaternion."""
    w, x, y, z = (float(c) for c in wxyz)
    return factory.make('geometry_msgs/msg/Quaternion', x=x, y=y, z=z, w=w)


def _transform_stamped(factory, t, parent, child, translation, wxyz):
    transform = factory.make('geometry_msgs/msg/Transform',
                             translation=_vector3(factory, translation),
                             rotation=_quaternion(factory, wxyz))
    return factory.make('geometry_msgs/msg/TransformStamped', header=header(factory, t, parent),
                        child_frame_id=child, transform=transform)


def clock_message(factory, state):
    """rosgraph_msgs/Clock carrying the sim time."""
    return factory.make('rosgraph_msgs/msg/Clock', clock=stamp(factory, state.time))


def joint_state_message(factory, state):
    """sensor_msgs/JointState: names, position (rad or m), velocity (rad/s or m/s), effort
    (N m or N) in the scene's joint order; frame_id '' (joint states have no frame)."""
    return factory.make(
        'sensor_msgs/msg/JointState',
        header=header(factory, state.time, ''),
        name=[str(n) for n in state.joint_names],
        position=factory.float64_sequence(state.joint_positions),
        velocity=factory.float64_sequence(state.joint_velocities),
        effort=factory.float64_sequence(state.joint_efforts))


def odometry_message(factory, state):
    """nav_msgs/Odometry of the base frame (`state.base_frame`) in odom (REP 105).

    pose: the base frame's position (m) and orientation in odom. twist: linear (m/s) and
    angular (rad/s) velocity expressed in the base frame (the child frame). Covariances:
    ODOM_COVARIANCE.
    """
    pose = factory.make('geometry_msgs/msg/Pose', position=_point(factory, state.base_position),
                        orientation=_quaternion(factory, state.base_quaternion_wxyz))
    twist = factory.make('geometry_msgs/msg/Twist',
                         linear=_vector3(factory, state.base_linear_velocity),
                         angular=_vector3(factory, state.base_angular_velocity))
    return factory.make(
        'nav_msgs/msg/Odometry',
        header=header(factory, state.time, topics.ODOM_FRAME),
        child_frame_id=state.base_frame,
        pose=factory.make('geometry_msgs/msg/PoseWithCovariance', pose=pose,
                          covariance=factory.float64_array(ODOM_COVARIANCE, 36)),
        twist=factory.make('geometry_msgs/msg/TwistWithCovariance', twist=twist,
                           covariance=factory.float64_array(ODOM_COVARIANCE, 36)))


def tf_message(factory, state):
    """tf2_msgs/TFMessage: odom -> the base frame, then odom -> rft/<leg> for every leg (at
    the leg's reference point, identity rotation)."""
    transforms = [_transform_stamped(factory, state.time, topics.ODOM_FRAME, state.base_frame,
                                     state.base_position, state.base_quaternion_wxyz)]
    transforms += [_transform_stamped(factory, state.time, topics.ODOM_FRAME,
                                      topics.leg_frame_id(leg.name), leg.point, _IDENTITY_WXYZ)
                   for leg in state.legs]
    return factory.make('tf2_msgs/msg/TFMessage', transforms=transforms)


def leg_wrench_message(factory, state, leg):
    """geometry_msgs/WrenchStamped of one leg's summed RFT wrench, in frame rft/<leg>.

    force (N) in world (odom) axes, so force.z is the vertical ground force; torque (N m)
    about the leg's reference point, world axes.
    """
    wrench = factory.make('geometry_msgs/msg/Wrench', force=_vector3(factory, leg.force),
                          torque=_vector3(factory, leg.torque))
    return factory.make('geometry_msgs/msg/WrenchStamped',
                        header=header(factory, state.time, topics.leg_frame_id(leg.name)),
                        wrench=wrench)


#: visualization_msgs/Marker actions.
MARKER_ADD, MARKER_DELETE, MARKER_DELETEALL = 0, 2, 3


def _marker(factory, t, ns, marker_id, marker_type, points, colors, scale, action=None):
    """visualization_msgs/Marker in odom at sim time `t` (s): `points` (m) with `colors`
    (ColorRGBA each), `scale` (m); `action`, by default ADD, or DELETE when there are no
    points."""
    if action is None:
        action = MARKER_ADD if len(points) else MARKER_DELETE
    no_data = factory.uint8_sequence([])
    return factory.make(
        'visualization_msgs/msg/Marker',
        header=header(factory, t, topics.ODOM_FRAME),
        ns=ns,
        id=marker_id,
        type=marker_type,
        action=action,
        pose=factory.make('geometry_msgs/msg/Pose', position=_point(factory, (0.0, 0.0, 0.0)),
                          orientation=_quaternion(factory, _IDENTITY_WXYZ)),
        scale=_vector3(factory, scale),
        color=factory.make('std_msgs/msg/ColorRGBA', r=1.0, g=1.0, b=1.0, a=1.0),
        lifetime=factory.make('builtin_interfaces/msg/Duration', sec=0, nanosec=0),
        frame_locked=False,
        points=[_point(factory, p) for p in points],
        colors=colors,
        texture_resource='',
        texture=factory.make('sensor_msgs/msg/CompressedImage', header=header(factory, 0.0, ''),
                             format='', data=no_data),
        uv_coordinates=[],
        text='',
        mesh_resource='',
        mesh_file=factory.make('visualization_msgs/msg/MeshFile', filename='', data=no_data),
        mesh_use_embedded_materials=False)


def _colors(factory, rgba):
    return [factory.make('std_msgs/msg/ColorRGBA', r=float(r), g=float(g), b=float(b),
                         a=float(a)) for r, g, b, a in rgba]


def plate_colors(stress_pa, zeta_n_per_cm3):
    """(K, 4) float32 RGBA in [0, 1] (the precision of std_msgs/ColorRGBA): blue at no
    stress to red at stress >= zeta * PLATE_STRESS_FULL_SCALE_DEPTH_M (Pa)."""
    full_scale = zeta_to_si(zeta_n_per_cm3) * PLATE_STRESS_FULL_SCALE_DEPTH_M
    s = np.clip(np.asarray(stress_pa, dtype=float) / full_scale, 0.0, 1.0)
    return np.column_stack([s, np.zeros_like(s), 1.0 - s, np.ones_like(s)]).astype(np.float32)


def plates_message(factory, state):
    """visualization_msgs/MarkerArray with one SPHERE_LIST marker in odom: a sphere at each
    active plate (m), coloured by stress |F| / area (see `plate_colors`), sized by the
    square root of the mean plate area. With no active plate the marker is deleted."""
    plates = state.active_plates
    count = len(plates.areas)
    if count:
        stress = np.linalg.norm(plates.forces, axis=1) / plates.areas
        colors = _colors(factory, plate_colors(stress, state.zeta))
        size = float(np.sqrt(np.mean(plates.areas)))
    else:
        colors, size = [], 0.0
    marker = _marker(factory, state.time, PLATES_MARKER_NS, PLATES_MARKER_ID, 7,  # SPHERE_LIST
                     plates.positions, colors, (size, size, size))
    return _marker_array(factory, [marker])


def _marker_array(factory, markers):
    """visualization_msgs/MarkerArray of `markers` (Marker), applied by RViz in this order."""
    return factory.make(topics.MARKER_ARRAY_TYPE, markers=markers)


def terrain_cloud_message(factory, update):
    """sensor_msgs/PointCloud2 in odom of a `terrain.TerrainUpdate`: `update.points` as
    `update.shape` rows and columns, fields x, y, z (float32, m, little-endian, 12 bytes a
    point), dense. The whole grid is an organized cloud (height = the grid's rows ny > 1,
    width = its columns nx, row iy holding the nodes of y = origin + iy * spacing), the
    changed nodes an unorganized one (height 1), so `height > 1` tells the whole grid."""
    points = np.ascontiguousarray(update.points, dtype='<f4').reshape(-1, 3)
    height, width = update.shape
    fields = [factory.make('sensor_msgs/msg/PointField', name=name, offset=4 * k,
                           datatype=POINT_FIELD_FLOAT32, count=1)
              for k, name in enumerate('xyz')]
    return factory.make('sensor_msgs/msg/PointCloud2',
                        header=header(factory, update.time, topics.ODOM_FRAME),
                        height=height, width=width, fields=fields, is_bigendian=False,
                        point_step=12, row_step=12 * width,
                        data=factory.uint8_sequence(np.frombuffer(points.tobytes(), np.uint8)),
                        is_dense=True)


def terrain_colors(change_m):
    """(M, 4) float32 RGBA: grey for no change, to full blue at a dip of
    TERRAIN_CHANGE_FULL_SCALE_M or deeper, to full red at a pile that high or higher."""
    s = np.clip(np.asarray(change_m, dtype=float) / TERRAIN_CHANGE_FULL_SCALE_M, -1.0, 1.0)
    grey = 0.5 * (1.0 - np.abs(s))
    return np.column_stack([grey + np.maximum(s, 0.0), grey, grey + np.maximum(-s, 0.0),
                            np.ones_like(s)]).astype(np.float32)


def terrain_markers(factory, update):
    """[visualization_msgs/Marker] (odom, namespace TERRAIN_MARKER_NS) of a
    `terrain.TerrainUpdate`, in the order RViz is to apply them: a DELETEALL of the namespace
    first when the markers are sent whole (`update.clear`), then per tile of `update.tiles`
    (id = the tile's index) a POINTS marker of its nodes that differ from the pristine
    surface (x, y, z in m), coloured by height change (`terrain_colors`), each a square one
    node spacing wide, or DELETE when the tile is pristine. [] when no marker changed."""
    scale = (update.spacing, update.spacing, 0.0)
    markers = [_marker(factory, update.time, TERRAIN_MARKER_NS, 0, 8, [], [], scale,
                       MARKER_DELETEALL)] if update.clear else []
    markers += [_marker(factory, update.time, TERRAIN_MARKER_NS, tile.index, 8,  # POINTS
                        tile.deformed, _colors(factory, terrain_colors(tile.change)), scale)
                for tile in update.tiles]
    return markers


def terrain_messages(factory, update):
    """[(topic, message)] of a terrain publication: the cloud (unless `update` holds none),
    then one visualization_msgs/MarkerArray of all its markers (`terrain_markers`; none when
    no marker changed), so that a subscriber gets a publication's markers whole or not at
    all, whatever its queue depth."""
    cloud = [] if update.points is None else [
        (topics.TERRAIN, terrain_cloud_message(factory, update))]
    markers = terrain_markers(factory, update)
    array = [(topics.TERRAIN_MARKER, _marker_array(factory, markers))] if markers else []
    return cloud + array


@dataclass(frozen=True)
class DiagnosticFields:
    """The content of the one DiagnosticStatus on /diagnostics (`diagnostic_fields`): level
    (0 OK, 2 ERROR), name, message, hardware_id and the (key, value) texts."""
    level: int
    name: str
    message: str
    hardware_id: str
    values: tuple


def _text(value):
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    return str(value)


def diagnostic_fields(state, status):
    """What /diagnostics says about `state` and `status` (see `diagnostics_message`)."""
    rejected = dict(sorted(status.commands_rejected.items()))
    values = [('sim_time_s', float(state.time)),
              ('zeta_n_per_cm3', float(state.zeta)),
              ('real_time_factor', float(status.real_time_factor)),
              ('plates_active', int(state.plates_active)),
              ('stable', bool(status.stable)),
              ('paused', bool(status.paused)),
              ('commands_rejected', int(sum(rejected.values())))]
    values += [(f'commands_rejected.{reason}', int(n)) for reason, n in rejected.items()]
    values += [('kernels', status.kernels)] if status.kernels else []
    values += outcome_values(status.outcome)
    down = is_down(status.outcome)
    return DiagnosticFields(
        level=2 if not status.stable else 1 if down else 0,  # ERROR / WARN / OK
        name='rft_sim: simulation',
        message=status.problem if not status.stable else 'paused' if status.paused else 'running',
        hardware_id=status.scene,
        values=tuple((key, _text(value)) for key, value in values))


def diagnostics_message(factory, state, status):
    """diagnostic_msgs/DiagnosticArray with one status 'rft_sim: simulation'.

    level OK (message 'running' or 'paused'), WARN once the robot has fallen (the outcome),
    or ERROR once the run diverged (message = the problem). Values (floats round-trip
    through float()): sim_time_s, zeta_n_per_cm3, real_time_factor, plates_active, stable,
    paused, commands_rejected (total) and commands_rejected.<reason>, and the outcome's
    (`diagnostics.outcome_values`) where the status has one.
    """
    return diagnostic_array(factory, diagnostic_fields(state, status), state.time)


def diagnostic_array(factory, fields, t):
    """diagnostic_msgs/DiagnosticArray of one status, `fields` (DiagnosticFields), stamped
    with sim time `t` (s)."""
    diagnostic = factory.make(
        'diagnostic_msgs/msg/DiagnosticStatus',
        level=factory.byte(fields.level), name=fields.name, message=fields.message,
        hardware_id=fields.hardware_id,
        values=[factory.make('diagnostic_msgs/msg/KeyValue', key=key, value=value)
                for key, value in fields.values])
    return factory.make('diagnostic_msgs/msg/DiagnosticArray',
                        header=header(factory, t, ''), status=[diagnostic])


#: Covariance of a part an Imu message does not carry (REP 145: element 0 is -1).
UNKNOWN_COVARIANCE = np.array([-1.0] + [0.0] * 8)
_ZERO_COVARIANCE = np.zeros(9)
_NO_QUATERNION = (1.0, 0.0, 0.0, 0.0)


def _imu(factory, t, frame, quaternion_wxyz, angular_velocity, linear_acceleration,
         covariances):
    return factory.make(
        topics.IMU_TYPE, header=header(factory, t, frame),
        orientation=_quaternion(factory, quaternion_wxyz),
        orientation_covariance=factory.float64_array(covariances[0], 9),
        angular_velocity=_vector3(factory, angular_velocity),
        angular_velocity_covariance=factory.float64_array(covariances[1], 9),
        linear_acceleration=_vector3(factory, linear_acceleration),
        linear_acceleration_covariance=factory.float64_array(covariances[2], 9))


def imu_message(factory, t, reading):
    """sensor_msgs/Imu of an `ImuReading` at sim time `t` (s), in the IMU's frame: orientation
    in odom, angular velocity (rad/s) and specific force (m/s^2, +g up at rest) in IMU axes,
    the reading's covariances (0: exact)."""
    return _imu(factory, t, reading.frame, reading.quaternion_wxyz, reading.angular_velocity,
                reading.linear_acceleration,
                (reading.orientation_covariance, reading.angular_velocity_covariance,
                 reading.linear_acceleration_covariance))


def foot_contacts_message(factory, t, contacts):
    """sensor_msgs/JointState of `FootContacts` at sim time `t` (s): name = the legs,
    position = stance (1.0) or swing (0.0), velocity empty, effort = normal force (N)."""
    return factory.make(
        topics.JOINT_STATE_TYPE, header=header(factory, t, ''), name=list(contacts.legs),
        position=factory.float64_sequence(contacts.stance.astype(float)),
        velocity=factory.float64_sequence([]),
        effort=factory.float64_sequence(contacts.normal_force))


def model_sensor_message(factory, t, sensor):
    """The message of a `ModelSensor` at sim time `t` (s), of its kind's type
    (`topics.MODEL_SENSOR_TYPES`), in its site's or body's frame: touch -> WrenchStamped
    force.z (N, the site's normal), force / torque -> WrenchStamped force / torque (site
    axes), gyro / accelerometer / framequat -> Imu with that part only (the others' covariance
    element 0 is -1: not carried), any other -> Float64MultiArray of its values (one
    dimension labelled with the sensor's name)."""
    kind, values = sensor.kind, [float(v) for v in sensor.values]
    msgtype = topics.MODEL_SENSOR_TYPES.get(kind, topics.FLOAT64_ARRAY_TYPE)
    zero = (0.0, 0.0, 0.0)
    if msgtype == topics.WRENCH_TYPE:
        force = (0.0, 0.0, values[0]) if kind == 'touch' else values if kind == 'force' else zero
        torque = values if kind == 'torque' else zero
        wrench = factory.make('geometry_msgs/msg/Wrench', force=_vector3(factory, force),
                              torque=_vector3(factory, torque))
        return factory.make(msgtype, header=header(factory, t, sensor.frame), wrench=wrench)
    if msgtype == topics.IMU_TYPE:
        parts = {'framequat': 0, 'gyro': 1, 'accelerometer': 2}
        covariances = [UNKNOWN_COVARIANCE] * 3
        covariances[parts[kind]] = _ZERO_COVARIANCE
        return _imu(factory, t, sensor.frame,
                    values if kind == 'framequat' else _NO_QUATERNION,
                    values if kind == 'gyro' else zero,
                    values if kind == 'accelerometer' else zero, covariances)
    dimension = factory.make('std_msgs/msg/MultiArrayDimension', label=sensor.name,
                             size=len(values), stride=len(values))
    return factory.make(msgtype, layout=factory.make('std_msgs/msg/MultiArrayLayout',
                                                     dim=[dimension], data_offset=0),
                        data=factory.float64_sequence(values))


def sensor_messages(factory, state, imu_topic=topics.IMU):
    """[(topic, message)] of the state's sensor readings (`state.sensors`; none when None):
    the IMU on `imu_topic`, the foot contacts, each model sensor on its own topic."""
    readings = state.sensors
    if readings is None:
        return []
    out = []
    if readings.imu is not None:
        out.append((imu_topic, imu_message(factory, state.time, readings.imu)))
    if readings.contacts is not None:
        out.append((topics.FOOT_CONTACTS,
                    foot_contacts_message(factory, state.time, readings.contacts)))
    return out + model_sensor_messages(factory, state)


def model_sensor_messages(factory, state):
    """[(topic, message)] of the model sensors' readings the state carries."""
    return [(topics.model_sensor_topic(sensor.name),
             model_sensor_message(factory, state.time, sensor))
            for sensor in state.sensors.model_sensors]


def state_messages(factory, state, *, plates, imu_topic=topics.IMU):
    """[(topic, message)] of one publishing cycle: /clock, /joint_states, /odom, /tf, one
    wrench per leg, if `plates` and the state carries active plates, /rft/plates, then the
    sensor readings it carries (`sensor_messages`, the IMU on `imu_topic`)."""
    out = [(topics.CLOCK, clock_message(factory, state)),
           (topics.JOINT_STATES, joint_state_message(factory, state)),
           (topics.ODOM, odometry_message(factory, state)),
           (topics.TF, tf_message(factory, state))]
    out += [(topics.leg_wrench_topic(leg.name), leg_wrench_message(factory, state, leg))
            for leg in state.legs]
    if plates and state.active_plates is not None:
        out.append((topics.PLATES, plates_message(factory, state)))
    return out + sensor_messages(factory, state, imu_topic)


def duration(factory, seconds):
    """builtin_interfaces/Duration of `seconds` (s), rounded to the nearest nanosecond."""
    sec, nanosec = split_ns(seconds_to_ns(seconds))
    return factory.make('builtin_interfaces/msg/Duration', sec=sec, nanosec=nanosec)


def trajectory_point(factory, positions, velocities, time_from_start):
    """trajectory_msgs/JointTrajectoryPoint: positions (rad or m), velocities (rad/s or m/s;
    empty for none), time_from_start (s); accelerations and efforts empty."""
    empty = factory.float64_sequence([])
    return factory.make('trajectory_msgs/msg/JointTrajectoryPoint',
                        positions=factory.float64_sequence(positions),
                        velocities=factory.float64_sequence(velocities),
                        accelerations=empty, effort=empty,
                        time_from_start=duration(factory, time_from_start))


def joint_trajectory_message(factory, command):
    """trajectory_msgs/JointTrajectory of a `TrajectoryCommand` (what a gait publisher
    sends): header.stamp = start time (sim time, s; 0 = start on receipt), frame_id '';
    per point positions (rad or m), velocities (rad/s or m/s; empty when not given) and
    time_from_start (s). Accelerations and efforts are left empty."""
    points = [trajectory_point(factory, point.positions, point.velocities or [],
                               point.time_from_start)
              for point in command.points]
    return factory.make('trajectory_msgs/msg/JointTrajectory',
                        header=header(factory, command.start_time, ''),
                        joint_names=[str(n) for n in command.joint_names], points=points)
