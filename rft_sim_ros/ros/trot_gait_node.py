"""The `trot_gait` node (`ros2 run rft_sim_ros trot_gait`): drives the bundled quadruped's
trot (rft_sim_ros.scenes.quadruped.TrotGait) over /joint_trajectory_controller/joint_trajectory,
as `tripod_gait` does for the hexapod (rft_sim_ros.ros.gait_node.GaitNode: sim time, short
trajectories of future targets).

Parameters (read at start): frequency (Hz, trot cycles per second), stance_fraction,
step_length (m), step_height (m), ramp_time (s), stand_hip and stand_knee (rad, the standing
pose the trot starts from: the model's ros2_control initial values), and those of every gait
node: start_delay, rate, horizon, spacing.
"""
import sys

from rft_sim_ros.ros.gait_node import GaitNode
from rft_sim_ros.scenes.quadruped import STAND_HIP, STAND_KNEE, TrotGait


class TrotGaitNode(GaitNode):
    """The quadruped's trot (see module docstring)."""
    NODE_NAME = 'trot_gait'
    GAIT_PARAMETERS = {
        'frequency': (1.5, 'frequency_hz', 'trot cycles per second, Hz'),
        'stance_fraction': (0.6, 'stance_fraction', 'fraction of a cycle a foot is in stance'),
        'step_length': (0.08, 'step_length_m', 'fore-aft stroke of a foot, m'),
        'step_height': (0.05, 'step_height_m', 'lift of a foot in swing, m'),
        'ramp_time': (0.5, 'ramp_time_s', 'time over which stroke and lift grow from 0, s'),
        'stand_hip': (STAND_HIP, 'stand_hip', 'hip pitch of the standing pose, rad'),
        'stand_knee': (STAND_KNEE, 'stand_knee', 'knee of the standing pose, rad'),
    }

    @staticmethod
    def make_gait(start_time_s, **keywords):
        return TrotGait(start_time_s=start_time_s, **keywords)


def main(args=None):
    """Entry point of `ros2 run rft_sim_ros trot_gait`; returns the exit status."""
    return TrotGaitNode.main(args)


if __name__ == '__main__':
    sys.exit(main())
