"""Recorded joint commands replayed in sim time (`rft-sim run ... --commands FILE`).

`load_commands(path)` reads a file of commands into a `CommandReplay`, whose `schedule()`
gives run_scene's (time_s, action) pairs: each action hands its command to the simulation's
`CommandHandler` at that sim time, through the same readers and checks as the node's
topics (`inbound`, `joint_state_commands`, the handler's validation). A command the handler
rejects stops the run with one line naming the file, the time, the topic and the reason.

Files:

* a rosbag2 folder (what `ros2 bag record` wrote; rosbags reads it): its command topics,
  each message at its recorded time after the bag's start:
  trajectory_msgs/JointTrajectory (a joint_trajectory_controller's topic; a header stamp,
  rebased the same way, defers its start as on the live topic), std_msgs/Float64MultiArray
  (forward command controllers: an 'effort' or 'velocity' in the topic's name makes it that
  controller's, any other is positions; values in the scene's commanded-joint order) and
  sensor_msgs/JointState on a topic whose name holds 'command' (ros2_control's topic
  hardware interface; /joint_states and the like are states, not commands).
* a CSV file: a header `time,JOINT,JOINT,...`, then one row of positions (rad or m) per
  waypoint time (s after the start, increasing): one trajectory through those waypoints
  from t = 0, linear between them, as joint_trajectory_controller follows positions-only
  waypoints; joints not in the header hold.
* a YAML file: {joint_names: [...], points: [{time: s, positions: [...], velocities:
  [...] (optional)}, ...]}: the same trajectory, cubic where velocities are given.

A file that cannot be read raises ValueError with one line saying what and where.
"""
import csv
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, List

import yaml

from rft_sim_ros.control.commands import CommandRejected, TrajectoryCommand, TrajectoryPoint
from rft_sim_ros.control.joint_state_commands import read_joint_state_command
from rft_sim_ros.ros import inbound, topics
from rft_sim_ros.stamps import NS_PER_S

#: Message types a bag's command topics carry.
_TRAJECTORY, _ARRAY, _JOINT_STATE = (topics.JOINT_TRAJECTORY_TYPE, topics.FLOAT64_ARRAY_TYPE,
                                     topics.JOINT_STATE_TYPE)


@dataclass(frozen=True)
class TimedCommand:
    """One command: sim time (s), the topic it came on (for messages), its kind
    ('trajectory', 'position', 'velocity', 'effort', 'joint_state') and its content (a
    TrajectoryCommand, a list of values, or a JointState message)."""
    time: float
    topic: str
    kind: str
    content: Any


def _apply(sim, command):
    """Hand `command` to `sim.commands` now; the handler's CommandResult."""
    commands = sim.commands
    if commands is None:
        raise ValueError(f'{sim.no_commands_reason()}: no joint to replay commands to')
    now = sim.time
    if command.kind == 'trajectory':
        return commands.set_trajectory(command.content, now)
    if command.kind == 'joint_state':
        index = {name: i for i, name in enumerate(commands.joint_names)}
        try:
            read = read_joint_state_command(command.content, index,
                                            sim.description.command_interfaces,
                                            sim.passive_joint_names)
        except CommandRejected as rejected:
            return rejected.result
        return commands.set_joint_states(read, now)
    apply = {'position': commands.set_positions, 'velocity': commands.set_velocities,
             'effort': commands.set_efforts}[command.kind]
    return apply(command.content, now)


class CommandReplay:
    """The commands of file `source`, in time order (`commands`: TimedCommands)."""

    def __init__(self, source, commands: List[TimedCommand]):
        self.source = source
        self.commands = sorted(commands, key=lambda c: c.time)
        self.applied = 0

    def schedule(self):
        """run_scene's schedule: (time_s, action) per command; an action raises ValueError
        (one line) when the handler rejects its command."""
        return [(command.time, lambda sim, command=command: self._run(sim, command))
                for command in self.commands]

    def _run(self, sim, command):
        result = _apply(sim, command)
        if not result.accepted:
            raise ValueError(f'{self.source}: the command at t = {command.time:.6g} s on '
                             f'{command.topic} was rejected ({result.reason.value}): '
                             f'{result.message}')
        self.applied += 1


def load_commands(path):
    """`CommandReplay` of the bag folder, CSV or YAML file at `path` (module docstring);
    raises ValueError (one line) when it cannot be read."""
    path = Path(path)
    if path.is_dir():
        commands = _bag_commands(path)
    elif not path.is_file():
        raise ValueError(f'--commands {path}: no such file or folder')
    elif path.suffix.lower() == '.csv':
        commands = [_csv_trajectory(path)]
    elif path.suffix.lower() in ('.yaml', '.yml'):
        commands = [_yaml_trajectory(path)]
    else:
        raise ValueError(f'--commands {path}: give a rosbag2 folder, a .csv or a .yaml file')
    return CommandReplay(str(path), commands)


def _array_kind(topic):
    name = topic.lower()
    return 'effort' if 'effort' in name else 'velocity' if 'velocity' in name else 'position'


def _bag_commands(path):
    from rosbags.rosbag2 import Reader
    from rft_sim_ros.ros.factory import jazzy_typestore
    typestore = jazzy_typestore()
    try:
        reader = Reader(path)
        reader.open()
    except Exception as error:  # rosbags raises its own errors for anything unreadable
        raise ValueError(f'--commands {path}: not a readable rosbag2 folder ({error})') from None
    try:
        wanted = [c for c in reader.connections
                  if c.msgtype in (_TRAJECTORY, _ARRAY)
                  or (c.msgtype == _JOINT_STATE and 'command' in c.topic.lower())]
        if not wanted:
            found = ', '.join(sorted({f'{c.topic} ({c.msgtype})' for c in reader.connections}))
            raise ValueError(f'--commands {path}: no command topic in the bag (JointTrajectory, '
                             f'Float64MultiArray, JointState on a *command* topic); it has '
                             f'{found or "no topics"}')
        start_ns = reader.start_time
        commands = []
        for connection, time_ns, data in reader.messages(connections=wanted):
            msg = typestore.deserialize_cdr(data, connection.msgtype)
            t = (time_ns - start_ns) / NS_PER_S
            if connection.msgtype == _TRAJECTORY:
                command = inbound.trajectory_command(msg)
                stamp = command.start_time
                start = 0.0 if stamp == 0.0 else max(0.0, stamp - start_ns / NS_PER_S)
                commands.append(TimedCommand(t, connection.topic, 'trajectory',
                                             replace(command, start_time=start)))
            elif connection.msgtype == _ARRAY:
                commands.append(TimedCommand(t, connection.topic, _array_kind(connection.topic),
                                             inbound.array_command(msg)))
            else:
                commands.append(TimedCommand(t, connection.topic, 'joint_state', msg))
    finally:
        reader.close()
    return commands


def _number(text, where):
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise ValueError(f'{where}: {text!r} is not a number') from None
    if not math.isfinite(value):
        raise ValueError(f'{where}: {text!r} is not a finite number')
    return value


def _csv_trajectory(path):
    try:
        rows = list(csv.reader(path.read_text().splitlines()))
    except (OSError, UnicodeDecodeError, csv.Error) as error:
        raise ValueError(f'--commands {path}: cannot read it ({error})') from None
    rows = [row for row in rows if row and any(cell.strip() for cell in row)]
    if len(rows) < 2 or [c.strip() for c in rows[0]][:1] != ['time'] or len(rows[0]) < 2:
        raise ValueError(f'--commands {path}: a CSV of joint targets starts with the header '
                         f'time,JOINT,JOINT,... and has a row per waypoint')
    names = [c.strip() for c in rows[0][1:]]
    points = []
    for line, row in enumerate(rows[1:], start=2):
        where = f'--commands {path}, line {line}'
        if len(row) != len(rows[0]):
            raise ValueError(f'{where}: {len(row)} values, the header has {len(rows[0])}')
        values = [_number(cell.strip(), where) for cell in row]
        points.append(TrajectoryPoint(positions=values[1:], time_from_start=values[0]))
    return TimedCommand(0.0, str(path), 'trajectory',
                        TrajectoryCommand(joint_names=tuple(names), points=tuple(points)))


def _yaml_trajectory(path):
    try:
        content = yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as error:
        first = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise ValueError(f'--commands {path}: not valid YAML ({first})') from None
    shape = ('{joint_names: [...], points: [{time: s, positions: [...], velocities: [...]}, '
             '...]}')
    if not isinstance(content, dict) or set(content) != {'joint_names', 'points'} \
            or not isinstance(content['joint_names'], list) \
            or not isinstance(content['points'], list):
        raise ValueError(f'--commands {path}: write {shape}')
    points = []
    for i, point in enumerate(content['points']):
        where = f'--commands {path}, point {i}'
        if not isinstance(point, dict) or not {'time', 'positions'} <= set(point) \
                or not set(point) <= {'time', 'positions', 'velocities'}:
            raise ValueError(f'{where}: write {{time: s, positions: [...], velocities: [...]}}')
        points.append(TrajectoryPoint(positions=point['positions'],
                                      time_from_start=_number(point['time'], where),
                                      velocities=point.get('velocities')))
    return TimedCommand(0.0, str(path), 'trajectory',
                        TrajectoryCommand(joint_names=tuple(map(str, content['joint_names'])),
                                          points=tuple(points)))
