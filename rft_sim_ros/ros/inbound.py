"""Read incoming command messages into the ROS-free inputs of `CommandHandler`.

Duck-typed: works on rclpy messages and on rosbags messages alike. Nothing is validated
here; `CommandHandler` checks every value and rejects bad commands with a reason.
"""
from rft_sim_ros.ros.stamps import ros_time_to_seconds
from rft_sim_ros.control.commands import TrajectoryCommand, TrajectoryPoint


def trajectory_command(msg):
    """`TrajectoryCommand` from a trajectory_msgs/JointTrajectory.

    start_time = header.stamp in s (0 = start on receipt); per point: positions, velocities
    (empty = positions only) and time_from_start in s. Accelerations and effort are ignored.
    """
    return TrajectoryCommand(
        joint_names=tuple(msg.joint_names),
        points=tuple(TrajectoryPoint(positions=list(p.positions),
                                     velocities=list(p.velocities),
                                     time_from_start=ros_time_to_seconds(p.time_from_start))
                     for p in msg.points),
        start_time=ros_time_to_seconds(msg.header.stamp))


def array_command(msg):
    """The values of a std_msgs/Float64MultiArray (layout ignored, as
    forward_command_controller does): one position or effort per joint, `joint_names` order."""
    return list(msg.data)
