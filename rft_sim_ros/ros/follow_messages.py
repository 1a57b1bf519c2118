"""The messages of control_msgs/action/FollowJointTrajectory (control_msgs 5.x, ROS 2
Jazzy) that the `rft_sim` node's action server sends: feedback and result (a goal is read by
`inbound.follow_goal`). ROS-free, through a message factory (`rft_sim_ros.ros.factory`), as
`rft_sim_ros.ros.messages`; every field is set. Units SI; stamps are sim time.
"""
from rft_sim_ros.ros import topics
from rft_sim_ros.ros.messages import duration, header, trajectory_point

RESULT_TYPE = f'{topics.FOLLOW_JOINT_TRAJECTORY_TYPE}_Result'
FEEDBACK_TYPE = f'{topics.FOLLOW_JOINT_TRAJECTORY_TYPE}_Feedback'


def _empty_multi_dof_point(factory):
    return factory.make('trajectory_msgs/msg/MultiDOFJointTrajectoryPoint', transforms=[],
                        velocities=[], accelerations=[], time_from_start=duration(factory, 0.0))


def feedback_message(factory, feedback):
    """FollowJointTrajectory feedback of a `trajectory_goals.GoalFeedback`: stamped with
    its sim time, the commanded joints' desired, actual and error (desired - actual)
    positions and velocities, time_from_start = time since the trajectory's start; the
    multi-DOF fields empty."""
    def point(targets):
        return trajectory_point(factory, targets.positions, targets.velocities,
                                feedback.time_from_start)
    return factory.make(FEEDBACK_TYPE, header=header(factory, feedback.time, ''),
                        joint_names=[str(n) for n in feedback.joint_names],
                        desired=point(feedback.desired), actual=point(feedback.actual),
                        error=point(feedback.error), multi_dof_joint_names=[],
                        multi_dof_desired=_empty_multi_dof_point(factory),
                        multi_dof_actual=_empty_multi_dof_point(factory),
                        multi_dof_error=_empty_multi_dof_point(factory))


def result_message(factory, outcome):
    """FollowJointTrajectory result of a `trajectory_goals.GoalOutcome`."""
    return factory.make(RESULT_TYPE, error_code=int(outcome.error_code),
                        error_string=outcome.message)
