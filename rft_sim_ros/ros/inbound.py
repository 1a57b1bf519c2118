"""Read incoming command messages into the ROS-free inputs of `CommandHandler`.

Duck-typed: works on rclpy messages and on rosbags messages alike. Nothing is validated
here; `CommandHandler` checks every value and rejects bad commands with a reason.
"""
from rft_sim_ros.stamps import ros_time_to_seconds
from rft_sim_ros.control.commands import TrajectoryCommand, TrajectoryPoint
from rft_sim_ros.control.trajectory_goals import GoalRequest, JointTolerance


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


def _tolerances(entries):
    return tuple(JointTolerance(name=t.name, position=t.position, velocity=t.velocity,
                                acceleration=t.acceleration) for t in entries)


def follow_goal(msg):
    """`GoalRequest` from a control_msgs/action/FollowJointTrajectory goal: its trajectory
    (as `trajectory_command`), path and goal tolerances, goal_time_tolerance in s, and the
    counts of its multi-DOF waypoints and component tolerances (fields that older
    control_msgs lack count as empty)."""
    components = (len(getattr(msg, 'component_path_tolerance', ()))
                  + len(getattr(msg, 'component_goal_tolerance', ())))
    return GoalRequest(trajectory=trajectory_command(msg.trajectory),
                       path_tolerance=_tolerances(msg.path_tolerance),
                       goal_tolerance=_tolerances(msg.goal_tolerance),
                       goal_time_tolerance=ros_time_to_seconds(msg.goal_time_tolerance),
                       multi_dof_joints=len(msg.multi_dof_trajectory.points),
                       component_tolerances=components)
