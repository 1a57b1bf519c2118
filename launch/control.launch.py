"""The bundled quadruped in sand under a real ros2_control controller_manager.

  ros2 launch rft_sim_ros control.launch.py [hardware:=topic|topic_based]
      [controllers:=FILE] [scene_overrides:="[key=value, ...]"] [real_time_factor:=R]

Starts the simulator (`rft_sim`, scene quadruped with its built-in trot off, IMU and foot
contacts on), robot_state_publisher with the quadruped's description whose <ros2_control>
block uses the topic hardware interface (xacro argument hardware: `topic` =
joint_state_topic_hardware_interface/JointStateTopicSystem, `topic_based` = PickNik's
topic_based_ros2_control/TopicBasedSystem), then, once the simulator's first /clock has
come (ros2_control_node with use_sim_time aborts without one), ros2_control_node with the
controllers of config/ros2_control/quadruped_controllers.yaml, and the spawners:
joint_state_broadcaster and joint_trajectory_controller active, forward_position_controller
and forward_effort_controller loaded inactive.

The hardware and the simulator meet on /robot_joint_commands (sensor_msgs/JointState
commands) and /robot_joint_states. The simulator's own stand-in command interfaces are moved
out of the real controllers' way: its joint_trajectory_controller is served as
rft_sim/joint_trajectory_controller, its forward command topics and /joint_states under
/rft_sim/ (joint_state_broadcaster publishes /joint_states).
"""
import os

import yaml
from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, ExecuteProcess, OpaqueFunction,
                            RegisterEventHandler)
from launch.event_handlers import OnProcessExit
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from rft_sim_ros.robot.packages import PackageResolver
from rft_sim_ros.robot.xacro_files import expand_xacro

SHARE = get_package_share_directory('rft_sim_ros')
QUADRUPED = os.path.join(SHARE, 'models', 'quadruped', 'quadruped.urdf.xacro')
CONTROLLERS = os.path.join(SHARE, 'config', 'ros2_control', 'quadruped_controllers.yaml')
ACTIVE = ('joint_state_broadcaster', 'joint_trajectory_controller')
INACTIVE = ('forward_position_controller', 'forward_effort_controller')

ARGUMENTS = {
    'hardware': ('topic', 'topic hardware plugin: topic (JointStateTopicSystem) or '
                          'topic_based (TopicBasedSystem)'),
    'controllers': (CONTROLLERS, 'controllers YAML of the controller_manager'),
    'scene_overrides': ('[]', "scene values, YAML list of 'key=value' strings"),
    'real_time_factor': ('1.0', 'sim s per wall s; 0 = as fast as possible'),
}


def _text(context, name):
    return LaunchConfiguration(name).perform(context).strip()


def _nodes(context):
    hardware = _text(context, 'hardware')
    if hardware not in ('topic', 'topic_based'):
        raise ValueError(f'hardware must be topic or topic_based, got {hardware!r}')
    description = expand_xacro(QUADRUPED, PackageResolver(), {'hardware': hardware})
    overrides = yaml.safe_load(_text(context, 'scene_overrides') or '[]') or []
    simulator = Node(
        package='rft_sim_ros', executable='sim', name='rft_sim', output='screen',
        parameters=[{'scene': 'quadruped',
                     'scene_overrides': ['params.gait=none', *map(str, overrides)],
                     'real_time_factor': float(_text(context, 'real_time_factor')),
                     'trajectory_controller': 'rft_sim/joint_trajectory_controller'}],
        remappings=[('joint_states', 'rft_sim/joint_states'),
                    ('forward_position_controller/commands',
                     'rft_sim/forward_position_controller/commands'),
                    ('velocity_controller/commands', 'rft_sim/velocity_controller/commands'),
                    ('effort_controller/commands', 'rft_sim/effort_controller/commands')])
    state_publisher = Node(package='robot_state_publisher', executable='robot_state_publisher',
                           output='screen',
                           parameters=[{'robot_description': description,
                                        'use_sim_time': True}])
    wait_for_clock = ExecuteProcess(
        cmd=['ros2', 'topic', 'echo', '--once', '/clock', 'rosgraph_msgs/msg/Clock'],
        output='log')
    manager = Node(package='controller_manager', executable='ros2_control_node',
                   output='screen',
                   parameters=[_text(context, 'controllers'), {'use_sim_time': True}],
                   remappings=[('~/robot_description', '/robot_description')])
    spawners = [Node(package='controller_manager', executable='spawner', output='screen',
                     arguments=[*ACTIVE, '--param-file', _text(context, 'controllers')]),
                Node(package='controller_manager', executable='spawner', output='screen',
                     arguments=[*INACTIVE, '--inactive',
                                '--param-file', _text(context, 'controllers')])]
    return [simulator, state_publisher, wait_for_clock,
            RegisterEventHandler(OnProcessExit(target_action=wait_for_clock,
                                               on_exit=[manager, *spawners]))]


def generate_launch_description():
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=description)
         for name, (default, description) in ARGUMENTS.items()]
        + [OpaqueFunction(function=_nodes)])
