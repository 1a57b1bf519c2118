"""The hexapod walking in sand over ROS: `rft_sim` (scene hexapod with its built-in gait off,
so it takes commands from outside) driven by `tripod_gait` over the JointTrajectory topic,
and, with record:=true, `ros2 bag record` (MCAP, sim-time stamps) of the simulator's topics
(record.launch.py).

  ros2 launch rft_sim_ros walk.launch.py [zeta:=Z] [real_time_factor:=R] [record:=true]
      [bag:=DIR] [scene:=NAME|PATH] [scene_overrides:="[gait=none, payload=1.0]"]
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.conditions import IfCondition
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    share = get_package_share_directory('rft_sim_ros')
    sim = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(os.path.join(share, 'launch', 'sim.launch.py')),
        launch_arguments={name: LaunchConfiguration(name) for name in
                          ('scene', 'scene_overrides', 'zeta', 'real_time_factor')}.items())
    gait = Node(package='rft_sim_ros', executable='tripod_gait', name='tripod_gait',
                output='screen', parameters=[{'use_sim_time': True}])
    record = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(os.path.join(share, 'launch', 'record.launch.py')),
        launch_arguments={'bag': LaunchConfiguration('bag')}.items(),
        condition=IfCondition(LaunchConfiguration('record')))
    return LaunchDescription([
        DeclareLaunchArgument('scene', default_value='hexapod',
                              description='scene with the hexapod (models/hexapod.xml)'),
        DeclareLaunchArgument('scene_overrides', default_value='[gait=none]',
                              description="scene values, YAML list of 'key=value' strings; "
                                          'keep gait=none so tripod_gait drives the robot'),
        DeclareLaunchArgument('zeta', default_value='',
                              description="sand stiffness, N/cm^3 (default: the scene's)"),
        DeclareLaunchArgument('real_time_factor', default_value='',
                              description='sim s per wall s (default: parameters file)'),
        DeclareLaunchArgument('record', default_value='false',
                              description='record the simulator topics with ros2 bag (MCAP)'),
        DeclareLaunchArgument('bag', default_value='',
                              description='bag folder (default: ros2 bag record chooses)'),
        sim, gait, record])
