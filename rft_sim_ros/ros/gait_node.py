"""Gait publisher nodes: a built-in gait sent as short JointTrajectory messages over
/joint_trajectory_controller/joint_trajectory, in sim time.

`GaitNode` is the rclpy wiring around `GaitTrajectories`: on a sim-time timer (`rate` Hz) it
publishes a short trajectory of future gait targets stamped in sim time, which the
simulator (or a real joint_trajectory_controller) interpolates. The node runs on sim time
(it turns use_sim_time on), so it waits for /clock and stops when the simulation is paused.
Subclasses name the node, the gait's parameters and how to build the gait.

`tripod_gait` (`ros2 run rft_sim_ros tripod_gait`): the hexapod's alternating tripod
(rft_sim_ros.scenes.gaits). Parameters (read at start): frequency (Hz, gait cycles per
second), stance_fraction, step_length (m), step_height (m), ramp_time (s), and those of
every gait node: start_delay (s of sim time after the first /clock before walking), rate
(Hz of sim time), horizon (s), spacing (s between waypoints).
"""
import sys

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from rft_sim_ros.ros import messages, topics
from rft_sim_ros.ros.entry import run_node
from rft_sim_ros.ros.factory import RclpyFactory
from rft_sim_ros.ros.gait_trajectory import GaitTrajectories
from rft_sim_ros.stamps import NS_PER_S
from rft_sim_ros.scenes.gaits import make_gait

QUEUE_DEPTH = 10

#: Parameters of every gait node: name -> (default, description).
PUBLISHER_PARAMETERS = {
    'start_delay': (1.0, 'sim time after the first /clock before walking, s'),
    'rate': (20.0, 'trajectories published per second of sim time, Hz'),
    'horizon': (0.25, 'time covered by each trajectory, s'),
    'spacing': (0.02, 'time between waypoints, s'),
}


class GaitNode(Node):
    """Publishes gait trajectories in sim time (see module docstring).

    Subclasses set NODE_NAME, GAIT_PARAMETERS ({parameter: (default, gait keyword,
    description)}) and `make_gait(start_time_s, **keywords)`. Raises ValueError (saying
    what to fix) if a parameter is out of range.
    """
    NODE_NAME = None
    GAIT_PARAMETERS = {}

    @staticmethod
    def make_gait(start_time_s, **keywords):
        raise NotImplementedError

    def __init__(self, **kwargs):
        super().__init__(self.NODE_NAME, **kwargs)
        if not self.get_parameter('use_sim_time').value:
            self.set_parameters([Parameter('use_sim_time', Parameter.Type.BOOL, True)])
        specs = {**{name: (default, description)
                    for name, (default, _, description) in self.GAIT_PARAMETERS.items()},
                 **PUBLISHER_PARAMETERS}
        values = {name: float(self.declare_parameter(  # numbers: integers welcome too
                      name, default, ParameterDescriptor(description=description,
                                                         read_only=True,
                                                         dynamic_typing=True)).value)
                  for name, (default, description) in specs.items()}
        gait = {keyword: values[name]
                for name, (_, keyword, _) in self.GAIT_PARAMETERS.items()}
        self.make_gait(0.0, **gait)  # check the gait parameters now (raises ValueError)
        self._trajectories = GaitTrajectories(
            lambda start: self.make_gait(start, **gait),
            horizon_s=values['horizon'], spacing_s=values['spacing'],
            start_delay_s=values['start_delay'])
        if not values['rate'] > 0.0:
            raise ValueError(f'rate must be > 0 Hz, got {values["rate"]}')
        self._factory = RclpyFactory()
        self._publisher = self.create_publisher(
            self._factory.message_class(topics.JOINT_TRAJECTORY_TYPE),
            topics.relative(topics.JOINT_TRAJECTORY), QUEUE_DEPTH)
        self.create_timer(1.0 / values['rate'], self._publish)  # node clock: sim time

    def _publish(self):
        command = self._trajectories.command(self.get_clock().now().nanoseconds / NS_PER_S)
        if command is not None:
            self._publisher.publish(messages.joint_trajectory_message(self._factory, command))

    @classmethod
    def main(cls, args=None):
        """Entry point of `ros2 run rft_sim_ros <NODE_NAME>`; returns the exit status."""
        return run_node(cls, cls.NODE_NAME, (TypeError, ValueError), args)


class TripodGaitNode(GaitNode):
    """The hexapod's tripod gait (rft_sim_ros.scenes.gaits.TripodGait)."""
    NODE_NAME = 'tripod_gait'
    GAIT_PARAMETERS = {
        'frequency': (1.0, 'frequency_hz', 'gait cycles per second, Hz'),
        'stance_fraction': (0.5, 'stance_fraction', 'fraction of a cycle a foot is in stance'),
        'step_length': (0.05, 'step_length_m', 'fore-aft stroke of a foot tip, m'),
        'step_height': (0.06, 'step_height_m', 'lift of a foot tip in swing, m'),
        'ramp_time': (0.5, 'ramp_time_s', 'time over which stroke and lift grow from 0, s'),
    }

    @staticmethod
    def make_gait(start_time_s, **keywords):
        return make_gait('tripod', start_time_s=start_time_s, **keywords)


def main(args=None):
    """Entry point of `ros2 run rft_sim_ros tripod_gait`; returns the exit status."""
    return TripodGaitNode.main(args)


if __name__ == '__main__':
    sys.exit(main())
