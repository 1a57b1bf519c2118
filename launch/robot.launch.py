"""Any robot in sand over ROS: `rft_sim` with a robot file or description, the same
description on robot_state_publisher (when that package is installed: /robot_description,
/tf of the links), an optional controller node, and with record:=true `ros2 bag record`.

  ros2 launch rft_sim_ros robot.launch.py [model:=FILE] [robot_description:=XML]
      [sand_bodies:="A,B*"|auto] [keyframe:=NAME] [xacro_args:="[k=v, ...]"]
      [controller:=NAME|none] [trajectory_controller:=NAME]
      [scene_overrides:="[key=value, ...]"] [zeta:=Z] [real_time_factor:=R]
      [record:=true] [bag:=DIR]

model: MJCF (.xml), URDF (.urdf) or xacro (.xacro) file; default: the bundled quadruped
(models/quadruped/quadruped.urdf.xacro) in its scene `quadruped` with the built-in trot off,
driven by its default controller `trot_gait`. A URDF or
xacro model is expanded here (rft_sim_ros.robot.xacro_files: $(find), package:// through the
ament index) and that one XML string goes to both nodes; an MJCF model is passed by path
(robot_state_publisher reads URDF only, so it is not started then). controller: an
executable of rft_sim_ros run with use_sim_time (e.g. trot_gait), or none.
trajectory_controller: the name of the joint_trajectory_controller the simulator serves (its
topic /NAME/joint_trajectory and action /NAME/follow_joint_trajectory), for a stack written
for a robot whose controller has another name.
"""
import os

import yaml
from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription, OpaqueFunction
from launch.conditions import IfCondition
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from rft_sim_ros.robot.description import is_xml_string
from rft_sim_ros.robot.packages import PackageResolver
from rft_sim_ros.robot.xacro_files import expand_xacro

SHARE = get_package_share_directory('rft_sim_ros')
QUADRUPED = os.path.join(SHARE, 'models', 'quadruped', 'quadruped.urdf.xacro')

ARGUMENTS = {
    'model': (QUADRUPED, 'robot file: MJCF .xml, URDF .urdf or xacro .xacro'),
    'robot_description': ('', 'the robot as an XML string (replaces model)'),
    'sand_bodies': ('', "bodies that touch sand: 'A,B*' names or glob patterns, or auto"),
    'keyframe': ('', "initial pose: the model's keyframe of this name"),
    'xacro_args': ('[]', "xacro arguments of a xacro model, YAML list of 'k=v' strings"),
    'controller': ('', 'controller executable of rft_sim_ros (default: trot_gait for the '
                       'bundled quadruped, else none)'),
    'trajectory_controller': ('', 'name of the joint_trajectory_controller served '
                                  '(default: joint_trajectory_controller)'),
    'scene_overrides': ('[]', "scene values, YAML list of 'key=value' strings"),
    'zeta': ('', "sand stiffness, N/cm^3 (default: the scene's)"),
    'real_time_factor': ('1.0', 'sim s per wall s; 0 = as fast as possible'),
    'record': ('false', 'record the simulator topics with ros2 bag (MCAP)'),
    'bag': ('', 'bag folder (default: ros2 bag record chooses)'),
}


def _text(context, name):
    return LaunchConfiguration(name).perform(context).strip()


def _strings(context, name):
    value = yaml.safe_load(_text(context, name) or '[]') or []
    return [str(v) for v in (value if isinstance(value, list) else [value])]


def _description(context):
    """(URDF/MJCF XML string or None, model path or None) of the launch arguments."""
    text = _text(context, 'robot_description')
    if text:
        return text, None
    model = os.path.expanduser(_text(context, 'model'))
    if model.endswith('.xacro'):
        args = dict(item.split('=', 1) for item in _strings(context, 'xacro_args'))
        return expand_xacro(model, PackageResolver(), args), None
    if model.endswith('.urdf'):
        with open(model) as file:
            return file.read(), None
    return None, model


def _nodes(context):
    text, model = _description(context)
    quadruped = (os.path.abspath(_text(context, 'model')) == QUADRUPED
                 and not _text(context, 'robot_description'))
    parameters = {'real_time_factor': float(_text(context, 'real_time_factor')),
                  'scene_overrides': _strings(context, 'scene_overrides')}
    if quadruped:  # its scene (sand level, feet), built-in trot off: the controller drives
        parameters.update(scene='quadruped',
                          scene_overrides=['gait=none', *parameters['scene_overrides']])
    for name in ('sand_bodies', 'keyframe', 'zeta', 'trajectory_controller'):
        if _text(context, name):
            parameters[name] = (yaml.safe_load(_text(context, name)) if name == 'zeta'
                                else _text(context, name))
    parameters.update({'robot_description': text} if text else {'model': model})
    nodes = [Node(package='rft_sim_ros', executable='sim', name='rft_sim', output='screen',
                  parameters=[parameters])]
    if text and is_xml_string(text) and '<robot' in text[:2000]:
        try:
            get_package_share_directory('robot_state_publisher')
        except PackageNotFoundError:
            pass
        else:
            nodes.append(Node(package='robot_state_publisher',
                              executable='robot_state_publisher', output='screen',
                              parameters=[{'robot_description': text, 'use_sim_time': True}]))
    controller = _text(context, 'controller') or ('trot_gait' if quadruped else 'none')
    if controller != 'none':
        nodes.append(Node(package='rft_sim_ros', executable=controller, name=controller,
                          output='screen', parameters=[{'use_sim_time': True}]))
    return nodes


def generate_launch_description():
    record = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(os.path.join(SHARE, 'launch', 'record.launch.py')),
        launch_arguments={'bag': LaunchConfiguration('bag')}.items(),
        condition=IfCondition(LaunchConfiguration('record')))
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=description)
         for name, (default, description) in ARGUMENTS.items()]
        + [OpaqueFunction(function=_nodes), record])
