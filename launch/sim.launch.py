"""Start the sand simulator node `rft_sim` (executable `sim`).

  ros2 launch rft_sim_ros sim.launch.py [scene:=NAME|PATH] [zeta:=Z] [real_time_factor:=R]
      [scene_overrides:="[key=value, ...]"] [params_file:=PATH]

The parameters file (default: the package's config/sim.params.yaml) sets the node's
parameters; the arguments given on the command line override it (an empty argument leaves
the file's value). The node publishes /clock: start other nodes with use_sim_time:=true.
"""
import os

import yaml
from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

ARGUMENTS = {
    'scene': 'bundled scene name or path to a scene YAML',
    'zeta': 'sand stiffness, N/cm^3 (0 < zeta <= 100)',
    'real_time_factor': 'sim seconds per wall second; 0 = as fast as possible',
    'scene_overrides': "scene values as a YAML list of 'key=value' strings",
}


def _sim_node(context):
    overrides = {}
    for name in ARGUMENTS:
        text = LaunchConfiguration(name).perform(context).strip()
        if not text:
            continue
        if name == 'scene':
            overrides[name] = text
        elif name == 'scene_overrides':
            value = yaml.safe_load(text)
            overrides[name] = [str(v) for v in (value if isinstance(value, list) else [value])]
        else:
            overrides[name] = yaml.safe_load(text)
    return [Node(package='rft_sim_ros', executable='sim', name='rft_sim', output='screen',
                 parameters=[LaunchConfiguration('params_file').perform(context), overrides])]


def generate_launch_description():
    params_file = os.path.join(get_package_share_directory('rft_sim_ros'), 'config',
                               'sim.params.yaml')
    return LaunchDescription(
        [DeclareLaunchArgument('params_file', default_value=params_file,
                               description='ROS parameters file of the rft_sim node')]
        + [DeclareLaunchArgument(name, default_value='', description=description)
           for name, description in ARGUMENTS.items()]
        + [OpaqueFunction(function=_sim_node)])
