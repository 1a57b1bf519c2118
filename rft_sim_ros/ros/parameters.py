"""Parameters of the `rft_sim` node: names, meaning, which may change at runtime, checks.

ROS-free: the rclpy node declares its parameters from `PARAMETERS` (static ones read-only)
and asks `parameter_problem` before it accepts a change; a non-empty answer is the reason
`ros2 param set` prints. Defaults that depend on the scene (zeta, publish_rate,
joint_names) are taken from the loaded scene by the node. Light to import (no MuJoCo, no
numba): the node answers its parameters before the simulation's modules are imported; the
scene_overrides are read with the scene (`robot_source.scene_overrides`).
"""
import math
import re
from dataclasses import dataclass
from pathlib import Path

from rft_sim_ros.control.hybrid import gain_patterns
from rft_sim_ros.units import zeta_problem


@dataclass(frozen=True)
class ParameterSpec:
    """One node parameter: `dynamic` ones may be set while the node runs."""
    name: str
    description: str
    dynamic: bool


SCENE = 'scene'
MODEL = 'model'
ROBOT_DESCRIPTION = 'robot_description'
SAND_BODIES = 'sand_bodies'
KEYFRAME = 'keyframe'
SCENE_OVERRIDES = 'scene_overrides'
ZETA = 'zeta'
REAL_TIME_FACTOR = 'real_time_factor'
PUBLISH_RATE = 'publish_rate'
JOINT_NAMES = 'joint_names'
PAUSED = 'paused'
PLATES = 'plates'
TERRAIN_RATE = 'terrain_rate'
TRAJECTORY_CONTROLLER = 'trajectory_controller'
JOINT_COMMANDS_TOPIC = 'joint_commands_topic'
JOINT_STATES_TOPIC = 'joint_states_topic'
JOINT_GAINS = 'joint_gains'
VIEWER = 'viewer'
VIDEO_PATH = 'video_path'

PARAMETERS = (
    ParameterSpec(SCENE, 'bundled scene name, path to a scene YAML, or a robot file', False),
    ParameterSpec(MODEL, 'robot file (MJCF .xml, URDF .urdf, xacro .xacro) to put in sand; '
                         "with a scene, it replaces the scene's model", False),
    ParameterSpec(ROBOT_DESCRIPTION, 'the robot as an XML string (URDF or MJCF), as '
                                     'robot_state_publisher takes it; unset with scene and model '
                                     'unset too: read from /robot_description', False),
    ParameterSpec(SAND_BODIES, "bodies that touch sand (rft.sand_bodies): 'A,B*' names or glob "
                               "patterns, 'auto', or auto beside them ('auto,crate')", False),
    ParameterSpec(KEYFRAME, "initial pose: the model's keyframe of this name (robot.keyframe), "
                            'held until commands arrive (unset: the first of home, stand, '
                            'standing, default it has, else its first keyframe)', False),
    ParameterSpec(SCENE_OVERRIDES, "scene values as 'key=value' strings (as rft-sim run --set)",
                  False),
    ParameterSpec(ZETA, "sand stiffness, N/cm^3, 0 < zeta <= 100 (default: the scene's); "
                        'applies from the next step', True),
    ParameterSpec(REAL_TIME_FACTOR, 'sim seconds per wall second; 0 = as fast as possible', True),
    ParameterSpec(PUBLISH_RATE, "state messages per second of sim time (default: the scene's)",
                  False),
    ParameterSpec(JOINT_NAMES, 'joint order of /forward_position_controller/commands, '
                               '/velocity_controller/commands and /effort_controller/commands '
                               "(default: the scene's commanded joints)", False),
    ParameterSpec(PAUSED, 'stop stepping (sim time and /clock stand still)', True),
    ParameterSpec(PLATES, 'publish the active plates as markers on /rft/plates', False),
    ParameterSpec(TERRAIN_RATE, 'sand surface publications (/rft/terrain, /rft/terrain/marker) '
                                'per second of sim time, on average; only when it changed',
                  False),
    ParameterSpec(TRAJECTORY_CONTROLLER, 'name of the joint_trajectory_controller served: '
                                         'topic /NAME/joint_trajectory, action '
                                         '/NAME/follow_joint_trajectory', False),
    ParameterSpec(JOINT_COMMANDS_TOPIC, 'sensor_msgs/JointState commands of ros2_control\'s '
                                        'topic hardware interface (its joint_commands_topic)',
                  False),
    ParameterSpec(JOINT_STATES_TOPIC, 'the joint states for ros2_control\'s topic hardware '
                                      'interface (its joint_states_topic); /joint_states too',
                  False),
    ParameterSpec(JOINT_GAINS, "kp, kd of the JointState (hybrid) commands: 'PATTERN: {kp: X, "
                               "kd: Y}' strings, glob patterns, later ones win (default: the "
                               "scene's joint_gains, else the position servos' gains)", True),
    ParameterSpec(VIEWER, "open MuJoCo's interactive viewer on the simulation (needs a "
                          'display; the sand and plates drawn as in rft-sim videos)', False),
    ParameterSpec(VIDEO_PATH, 'record the simulation into this MP4 file (a new one), as rft-sim '
                              'run --video does; the scene\'s video.* keys (scene_overrides) '
                              'set camera, size and rate; finished when the node stops',
                  False),
)

SPECS = {spec.name: spec for spec in PARAMETERS}


def _number(value):
    """`value` as a finite float, or None if it is not a finite real number (bools excluded)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def parameter_problem(name, value):
    """Why `value` cannot be given to parameter `name` at runtime, or None if it can.

    zeta: see `rft_sim_ros.units.zeta_problem`; real_time_factor: a finite number >= 0;
    paused: a bool; joint_gains: 'PATTERN: {kp: X, kd: Y}' strings (`control.hybrid.
    gain_patterns`). Static parameters are read-only once the node has started.
    """
    spec = SPECS.get(name)
    if spec is None:
        return f'unknown parameter {name!r}; parameters are {", ".join(SPECS)}'
    if not spec.dynamic:
        return f'{name} is read-only while the node runs: restart the node to change it'
    if name == ZETA:
        return zeta_problem(value)
    if name == JOINT_GAINS:
        try:
            gain_patterns(list(value))
        except (TypeError, ValueError) as error:
            return f'{JOINT_GAINS}: {error}'
        return None
    if name == REAL_TIME_FACTOR:
        number = _number(value)
        if number is None:
            return f'real_time_factor must be a finite number, got {value!r}'
        if number < 0.0:
            return f'real_time_factor must be >= 0 (0 = as fast as possible), got {number}'
        return None
    if not isinstance(value, bool):
        return f'paused must be true or false, got {value!r}'
    return None


def publish_rate(value, name=PUBLISH_RATE):
    """`value` (Hz of sim time) as a float; raises ValueError unless finite and > 0.
    name: the parameter, for the message (publish_rate or terrain_rate)."""
    number = _number(value)
    if number is None or number <= 0.0:
        raise ValueError(f'{name} must be a finite number > 0 Hz, got {value!r}')
    return number


#: A ROS name: tokens of letters, digits and underscores, each starting with a letter,
#: separated by '/' (a leading '/' is allowed).
_ROS_NAME = re.compile(r'/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*\Z')


def topic_name(value, name):
    """Topic `value` of parameter `name` checked: a ROS name (as written, absolute or
    relative); raises ValueError."""
    if not isinstance(value, str) or not _ROS_NAME.match(value):
        raise ValueError(f"{name} must be a ROS topic name (letters, digits and underscores, "
                         f"each part starting with a letter, parts joined by '/'), got {value!r}")
    return value


def trajectory_controller(value):
    """The controller name `value` (e.g. 'arm_controller', 'left/joint_trajectory_controller')
    without a leading '/'; raises ValueError unless it is a ROS name."""
    if not isinstance(value, str) or not _ROS_NAME.match(value):
        raise ValueError(f"{TRAJECTORY_CONTROLLER} must be a ROS name (letters, digits and "
                         f"underscores, each part starting with a letter, parts joined by '/'), "
                         f'got {value!r}')
    return value.lstrip('/')


def video_file(value):
    """The new MP4 file of `video_path` (`value`), or None where it is empty; raises
    ValueError where it ends otherwise than .mp4, exists (a video is never replaced) or its
    folder does not."""
    if not value:
        return None
    path = Path(value).expanduser()
    if path.suffix.lower() != '.mp4':
        raise ValueError(f'{VIDEO_PATH} must name an .mp4 file, got {value!r}')
    if path.exists():
        raise ValueError(f'{VIDEO_PATH} {value!r} exists: remove it or name another file')
    if not path.parent.is_dir():
        raise ValueError(f'{VIDEO_PATH} {value!r}: no folder {str(path.parent)!r}')
    return path


#: rcl's error for a parameter rule (`-p NAME:=VALUE`) whose value is not YAML.
_RULE_ERROR = re.compile(r"Couldn't parse parameter override rule: '(?P<rule>.*?)'\. Error")
#: The source locations rcl appends to its error messages.
_RCL_SOURCE = re.compile(r', at /\S+:\d+')


def arguments_problem(rcl_error):
    """One line saying why the command line's ROS arguments cannot be read, from rcl's error
    message `rcl_error`: for a parameter rule, the rule and how to quote a value (ROS 2 reads
    -p values as YAML); for anything else, rcl's message without its source locations."""
    match = _RULE_ERROR.search(rcl_error)
    if match is None:
        return _RCL_SOURCE.sub('', rcl_error)
    return (f"the parameter rule '{match['rule']}' is not valid YAML (ROS 2 reads -p values "
            "as YAML): quote such a value, -p \"sand_bodies:='*_foot'\", and a list item that "
            "holds brackets, -p \"scene_overrides:=[sand.surface.type=grid, "
            "'sand.surface.size=[2,2]']\"")


def needs_topic(scene, model, robot_description):
    """Whether the node must wait for /robot_description (none of the parameters scene,
    model and robot_description set)."""
    return not (scene or model or robot_description)
