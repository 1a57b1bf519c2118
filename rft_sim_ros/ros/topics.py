"""Names of the ROS interface: topics, message types and TF frames (design.md section 5).

One table that the rclpy node (publishers, subscriptions) and the rosbag2 writer
(connections) both read, so a bag holds exactly the topics and types the node publishes.
"""
import re

#: TF frames (REP 105): `odom` is the fixed world frame of the simulation, z up; the base
#: frame is the robot's base body (`SimState.base_frame`).
ODOM_FRAME = 'odom'

CLOCK = '/clock'
JOINT_STATES = '/joint_states'
ODOM = '/odom'
TF = '/tf'
PLATES = '/rft/plates'
DIAGNOSTICS = '/diagnostics'
TERRAIN = '/rft/terrain'
TERRAIN_MARKER = '/rft/terrain/marker'

#: The name of the joint_trajectory_controller the node stands in for (the `rft_sim` node's
#: parameter trajectory_controller changes it: ROS 2 Jazzy cannot remap an action's name).
TRAJECTORY_CONTROLLER = 'joint_trajectory_controller'


def trajectory_topic(controller=TRAJECTORY_CONTROLLER):
    """joint_trajectory_controller `controller`'s trajectory topic."""
    return f'/{controller}/joint_trajectory'


def follow_trajectory_action(controller=TRAJECTORY_CONTROLLER):
    """joint_trajectory_controller `controller`'s action (FollowJointTrajectory)."""
    return f'/{controller}/follow_joint_trajectory'


#: Command topics of a ros2_control stack, so existing gait controllers drive the sim unchanged.
JOINT_TRAJECTORY = trajectory_topic()
POSITION_COMMANDS = '/forward_position_controller/commands'
VELOCITY_COMMANDS = '/velocity_controller/commands'
EFFORT_COMMANDS = '/effort_controller/commands'
FOLLOW_JOINT_TRAJECTORY = follow_trajectory_action()

#: ros2_control's topic hardware interfaces (joint_state_topic_hardware_interface/
#: JointStateTopicSystem, topic_based_ros2_control/TopicBasedSystem): their default topics
#: (hardware parameters joint_commands_topic, joint_states_topic). Commands: reliable, depth 1,
#: as they publish them; the state: reliable, which their SensorDataQoS (best effort)
#: subscriptions accept.
ROBOT_JOINT_COMMANDS = '/robot_joint_commands'
ROBOT_JOINT_STATES = '/robot_joint_states'
ROBOT_JOINT_COMMANDS_DEPTH = 1

#: Sensors (`rft_sim_ros.sim.sensors`): the IMU's default topic (scene key sensors.imu_topic),
#: the foot contacts (one sensor_msgs/JointState a cycle: name = legs, position = stance
#: 1/0, effort = normal force N), and the prefix of the model's own sensors' topics.
IMU = '/imu/data'
FOOT_CONTACTS = '/rft/foot_contacts'
MODEL_SENSORS = '/rft/sensors'

#: The robot's description, as robot_state_publisher publishes it (latched: transient local),
#: which the node reads where no scene, model or robot_description parameter is set.
ROBOT_DESCRIPTION = '/robot_description'

CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'
JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'
ODOMETRY_TYPE = 'nav_msgs/msg/Odometry'
TF_TYPE = 'tf2_msgs/msg/TFMessage'
WRENCH_TYPE = 'geometry_msgs/msg/WrenchStamped'
MARKER_ARRAY_TYPE = 'visualization_msgs/msg/MarkerArray'
POINT_CLOUD_TYPE = 'sensor_msgs/msg/PointCloud2'
DIAGNOSTICS_TYPE = 'diagnostic_msgs/msg/DiagnosticArray'
JOINT_TRAJECTORY_TYPE = 'trajectory_msgs/msg/JointTrajectory'
POSITION_COMMANDS_TYPE = 'std_msgs/msg/Float64MultiArray'
VELOCITY_COMMANDS_TYPE = 'std_msgs/msg/Float64MultiArray'
EFFORT_COMMANDS_TYPE = 'std_msgs/msg/Float64MultiArray'
FOLLOW_JOINT_TRAJECTORY_TYPE = 'control_msgs/action/FollowJointTrajectory'
IMU_TYPE = 'sensor_msgs/msg/Imu'
FLOAT64_ARRAY_TYPE = 'std_msgs/msg/Float64MultiArray'
ROBOT_DESCRIPTION_TYPE = 'std_msgs/msg/String'

#: Message types of the model's own sensors by MuJoCo kind (`sensors.ModelSensor.kind`):
#: forces as the force_torque_sensor_broadcaster publishes them, the imu parts as Imu;
#: every other kind a Float64MultiArray of its values.
MODEL_SENSOR_TYPES = {'touch': WRENCH_TYPE, 'force': WRENCH_TYPE, 'torque': WRENCH_TYPE,
                      'framequat': IMU_TYPE, 'gyro': IMU_TYPE, 'accelerometer': IMU_TYPE}

#: Every message type a run's bag may record (`published_topics` with plates, terrain and
#: every kind of sensor): `rft-sim warmup` fills the bag's type cache with them
#: (`jazzy_types`).
RECORDABLE_TYPES = frozenset({CLOCK_TYPE, JOINT_STATE_TYPE, ODOMETRY_TYPE, TF_TYPE,
                              DIAGNOSTICS_TYPE, WRENCH_TYPE, MARKER_ARRAY_TYPE,
                              POINT_CLOUD_TYPE, IMU_TYPE, FLOAT64_ARRAY_TYPE,
                              *MODEL_SENSOR_TYPES.values()})

#: Topics that stay global when the node runs in a namespace, as in ROS convention: one
#: clock, one tf tree, one diagnostics stream.
GLOBAL_TOPICS = (CLOCK, TF, DIAGNOSTICS)

_NAME_TOKEN = re.compile(r'[A-Za-z][A-Za-z0-9_]*\Z')


def relative(name):
    """The name a node gives topic or action `name` (as written here, absolute): relative,
    so that the node's namespace applies (`--ros-args -r __ns:=/go2` gives /go2/joint_states,
    as a namespaced ros2_control robot has), except the `GLOBAL_TOPICS`."""
    return name if name in GLOBAL_TOPICS else name.lstrip('/')


def resolved(name, namespace='/'):
    """Topic or action `name` as a node in `namespace` ('/' or '/go2') resolves it."""
    return name if name in GLOBAL_TOPICS else namespace.rstrip('/') + name


def _checked_leg(leg):
    if not _NAME_TOKEN.match(leg):
        raise ValueError(
            f'leg name {leg!r} cannot be used in a ROS topic or frame name: use letters, '
            'digits and underscores, starting with a letter')
    return leg


def leg_frame_id(leg):
    """TF frame of a leg's RFT wrench: 'rft/<leg>', child of odom, at the leg's reference
    point, axes parallel to odom (identity rotation), so force.z is the vertical force."""
    return f'rft/{_checked_leg(leg)}'


def leg_wrench_topic(leg):
    """Topic of a leg's geometry_msgs/WrenchStamped: '/rft/<leg>/wrench'."""
    return f'/rft/{_checked_leg(leg)}/wrench'


def model_sensor_topic(name):
    """Topic of the model's sensor `name`: '/rft/sensors/<name>', every character a ROS name
    cannot hold replaced by '_' (and '_' put before a leading digit)."""
    token = re.sub(r'[^A-Za-z0-9_]', '_', name)
    return f'{MODEL_SENSORS}/{token if token[:1].isalpha() else "_" + token}'


def sensor_topics(layout):
    """{topic: message type} of a `sensors.SensorLayout` (None: {}); raises ValueError when
    two model sensors' names give one topic."""
    if layout is None:
        return {}
    out = {}
    if layout.imu_topic:
        out[layout.imu_topic] = IMU_TYPE
    if layout.contact_legs is not None:
        out[FOOT_CONTACTS] = JOINT_STATE_TYPE
    for name, kind, _ in layout.model_sensors:
        topic = model_sensor_topic(name)
        if topic in out:
            raise ValueError(f'model sensor {name!r}: another sensor is published on {topic} '
                             'already: rename one')
        out[topic] = MODEL_SENSOR_TYPES.get(kind, FLOAT64_ARRAY_TYPE)
    return out


def published_topics(leg_names, *, plates, terrain=False, sensors=None):
    """{topic: message type} of everything the simulation publishes.

    leg_names: legs of the scene (one wrench topic each). plates: whether the active plates
    are published as markers on /rft/plates. terrain: whether the sand surface is published
    (grid surfaces: `rft_sim_ros.ros.terrain`) on /rft/terrain (a cloud) and
    /rft/terrain/marker (one MarkerArray a publication). sensors: the run's
    `sensors.SensorLayout` (`sensor_topics`), or None.
    """
    topics = {
        CLOCK: CLOCK_TYPE,
        JOINT_STATES: JOINT_STATE_TYPE,
        ODOM: ODOMETRY_TYPE,
        TF: TF_TYPE,
        DIAGNOSTICS: DIAGNOSTICS_TYPE,
    }
    for leg in leg_names:
        topic = leg_wrench_topic(leg)
        if topic in topics:
            raise ValueError(f'leg name {leg!r} appears twice')
        topics[topic] = WRENCH_TYPE
    if plates:
        topics[PLATES] = MARKER_ARRAY_TYPE
    if terrain:
        topics[TERRAIN] = POINT_CLOUD_TYPE
        topics[TERRAIN_MARKER] = MARKER_ARRAY_TYPE
    for topic, msgtype in sensor_topics(sensors).items():
        if topic in topics:
            raise ValueError(f'sensor topic {topic} is a topic of the simulation already')
        topics[topic] = msgtype
    return topics
