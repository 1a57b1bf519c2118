"""`ros2 bag record` (MCAP, sim-time stamps) of everything the rft_sim node publishes;
included by walk.launch.py and robot.launch.py with record:=true.

  ros2 launch rft_sim_ros record.launch.py [bag:=DIR]
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction
from launch.substitutions import LaunchConfiguration

#: Everything rft_sim publishes (topics.published_topics), as a `ros2 bag record -e` regex.
RECORDED_TOPICS = r'^/(clock|joint_states|odom|tf|diagnostics|rft/.+)$'


def _recorder(context):
    command = ['ros2', 'bag', 'record', '-s', 'mcap', '--use-sim-time', '-e', RECORDED_TOPICS]
    bag = LaunchConfiguration('bag').perform(context).strip()
    if bag:
        command += ['-o', bag]
    return [ExecuteProcess(cmd=command, output='screen')]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('bag', default_value='',
                              description='bag folder (default: ros2 bag record chooses)'),
        OpaqueFunction(function=_recorder)])
