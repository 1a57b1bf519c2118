"""FollowJointTrajectory goals, as joint_trajectory_controller follows them: tolerances,
outcomes, feedback, preemption and cancel, on the servo rig through the ROS-free runtime,
and their messages against control_msgs' definitions (rosbags, CDR)."""
import numpy as np
import pytest

from rft_sim_ros.control import trajectory_goals as goals
from rft_sim_ros.control.commands import Targets, TrajectoryCommand, TrajectoryPoint
from rft_sim_ros.control.trajectory_goals import (ErrorCode, FollowedGoal, GoalRequest,
                                                  GoalState, JointTolerance, goal_tolerances)
from rft_sim_ros.ros import follow_messages, inbound, messages, topics
from rft_sim_ros.ros.factory import RosbagsFactory
from rft_sim_ros.scenes.config import load_scene
from ros_test_support import (SERVO_RIG, Harness, control_msgs_typestore, messages_equal,
                              position_array)

FACTORY = RosbagsFactory(control_msgs_typestore())
JOINTS = ('hip', 'knee')


def request(*points, names=('hip',), start=0.0, path=(), goal=(), goal_time=0.0):
    """A GoalRequest; points: (time_from_start, positions)."""
    return GoalRequest(
        trajectory=TrajectoryCommand(joint_names=names, start_time=start, points=[
            TrajectoryPoint(positions=p, time_from_start=t) for t, p in points]),
        path_tolerance=path, goal_tolerance=goal, goal_time_tolerance=goal_time)


def _tolerances(entries):
    return [FACTORY.make('control_msgs/msg/JointTolerance', name=t.name,
                         position=float(t.position), velocity=float(t.velocity),
                         acceleration=float(t.acceleration)) for t in entries]


def goal_msg(req):
    """The FollowJointTrajectory goal a client sends for `req` (a GoalRequest)."""
    multi_dof = FACTORY.make('trajectory_msgs/msg/MultiDOFJointTrajectory',
                             header=messages.header(FACTORY, 0.0, ''), joint_names=[],
                             points=[])
    return FACTORY.make('control_msgs/action/FollowJointTrajectory_Goal',
                        trajectory=messages.joint_trajectory_message(FACTORY, req.trajectory),
                        multi_dof_trajectory=multi_dof,
                        path_tolerance=_tolerances(req.path_tolerance),
                        component_path_tolerance=[],
                        goal_tolerance=_tolerances(req.goal_tolerance),
                        component_goal_tolerance=[],
                        goal_time_tolerance=messages.duration(FACTORY, req.goal_time_tolerance))


# --- tolerances and outcomes (no simulation) ------------------------------------------------

def test_tolerances_default_to_none_and_minus_one_erases():
    tol = goal_tolerances(request((0.1, [0.2]), path=[JointTolerance('knee', 0.05, -1.0)],
                                  goal=[JointTolerance('hip', 0.01, 0.2)], goal_time=0.5),
                          JOINTS)
    assert tol.path_position.tolist() == [0.0, 0.05] and tol.path_velocity.tolist() == [0, 0]
    assert tol.goal_position.tolist() == [0.01, 0.0] and tol.goal_velocity.tolist() == [0.2, 0]
    assert tol.goal_time == 0.5


@pytest.mark.parametrize('req, words', [
    (request((0.1, [0.2]), path=[JointTolerance('ankle', 0.1)]), "joint 'ankle'"),
    (request((0.1, [0.2]), goal=[JointTolerance('hip', -0.5)]), 'position is -0.5'),
    (request((0.1, [0.2]), goal=[JointTolerance('hip', float('nan'))]), 'is nan'),
    (request((0.1, [0.2]), path=[JointTolerance('hip', 0.1, 0.0, 2.0)]), 'acceleration'),
    (request((0.1, [0.2]), goal_time=-2.0), 'goal_time_tolerance is -2'),
])
def test_bad_tolerances_are_refused_with_the_reason(req, words):
    with pytest.raises(ValueError, match=words):
        goal_tolerances(req, JOINTS)


def test_multi_dof_goals_are_refused():
    req = GoalRequest(trajectory=request((0.1, [0.2])).trajectory, multi_dof_joints=1)
    with pytest.raises(ValueError, match='multi_dof'):
        goal_tolerances(req, JOINTS)


def targets(*positions, velocities=(0.0, 0.0)):
    return Targets(np.array(positions, float), np.array(velocities, float))


def test_path_goal_and_goal_time_tolerances_decide_the_outcome():
    tol = goal_tolerances(request((1.0, [0.2]), path=[JointTolerance('hip', 0.1)],
                                  goal=[JointTolerance('hip', 0.01)], goal_time=0.5), JOINTS)
    goal = FollowedGoal(tol, start=2.0, end=3.0, joint_names=JOINTS)
    feedback, outcome = goal.check(2.5, targets(0.1, 0.0), targets(0.05, 0.3))
    assert outcome is None                           # 0.05 < 0.1 on the hip; knee unchecked
    assert feedback.error.positions.tolist() == pytest.approx([0.05, -0.3])
    assert feedback.time_from_start == 0.5 and feedback.joint_names == JOINTS
    outcome = goal.check(2.5, targets(0.2, 0.0), targets(0.05, 0.0))[1]
    assert outcome.error_code is ErrorCode.PATH_TOLERANCE_VIOLATED and 'hip' in outcome.message
    assert goal.check(3.2, targets(0.2, 0.0), targets(0.17, 0.0))[1] is None   # waits
    outcome = goal.check(3.6, targets(0.2, 0.0), targets(0.17, 0.0))[1]
    assert outcome.error_code is ErrorCode.GOAL_TOLERANCE_VIOLATED
    assert outcome.state is GoalState.ABORTED
    outcome = goal.check(3.4, targets(0.2, 0.0), targets(0.195, 0.0))[1]
    assert outcome.state is GoalState.SUCCEEDED and outcome.error_code is ErrorCode.SUCCESSFUL


def test_without_goal_time_tolerance_a_goal_waits_for_its_tolerance():
    tol = goal_tolerances(request((1.0, [0.2]), goal=[JointTolerance('hip', 0.01)]), JOINTS)
    goal = FollowedGoal(tol, start=0.0, end=1.0, joint_names=JOINTS)
    assert goal.check(100.0, targets(0.2, 0.0), targets(0.1, 0.0))[1] is None


# --- through the runtime, on the servo rig --------------------------------------------------

class Listener:
    """What the action server hands the runtime: records feedback and the outcome."""

    def __init__(self):
        self.feedback, self.outcomes, self.cancel = [], [], False

    def publish_feedback(self, feedback):
        self.feedback.append(feedback)

    def finish(self, outcome):
        self.outcomes.append(outcome)

    def cancel_requested(self):
        return self.cancel

    @property
    def outcome(self):
        assert len(self.outcomes) <= 1, 'a goal ends once'
        return self.outcomes[0] if self.outcomes else None


@pytest.fixture(scope='module')
def rig_scene():
    return load_scene(SERVO_RIG)


class Rig(Harness):
    """The servo rig's runtime, its initial state published."""

    def __init__(self, scene, **options):
        super().__init__(scene, **options)
        self.runtime.tick()

    def start(self, req):
        listener = Listener()
        assert self.runtime.goal_problem(goal_msg(req)) is None
        self.runtime.start_goal(goal_msg(req), listener)
        return listener

    @property
    def positions(self):
        return self.sink.states[-1].joint_positions


@pytest.fixture
def rig(rig_scene):
    return Rig(rig_scene)


def test_a_goal_succeeds_when_its_last_waypoint_is_due(rig):
    """No tolerances (the controller's defaults): success in the first cycle at or after the
    last waypoint; feedback every cycle, desired as the trajectory, error desired - actual."""
    listener = rig.start(request((0.2, [0.3])))
    rig.run(0.1)
    assert listener.outcome is None and len(listener.feedback) == 10
    rig.run(0.15)
    outcome = listener.outcome
    assert outcome.state is GoalState.SUCCEEDED and outcome.error_code is ErrorCode.SUCCESSFUL
    times = [f.time for f in listener.feedback]
    assert times == [s.time for s in rig.sink.states[1:len(times) + 1]]   # every cycle
    assert times[-1] == pytest.approx(0.2, abs=1e-9) and times[-2] < 0.2
    last = listener.feedback[-1]
    assert last.desired.positions.tolist() == pytest.approx([0.3, 0.0])
    np.testing.assert_allclose(last.error.positions,
                               last.desired.positions - last.actual.positions)
    np.testing.assert_allclose(last.actual.positions, rig.sink.states[len(times)].joint_positions)
    middle = listener.feedback[9]                                 # t = 0.1 s: halfway
    assert middle.desired.positions[0] == pytest.approx(0.15) and middle.time_from_start == \
        pytest.approx(0.1)
    rig.run(0.3)
    assert rig.positions[0] == pytest.approx(0.3, abs=0.01)      # the last waypoint is held


def test_a_goal_tolerance_waits_for_the_joint_to_arrive(rig):
    listener = rig.start(request((0.05, [0.4]), goal=[JointTolerance('hip', 0.005)]))
    rig.run(1.0)
    outcome = listener.outcome
    assert outcome.state is GoalState.SUCCEEDED
    ended = listener.feedback[-1]
    assert ended.time > 0.06 and abs(ended.error.positions[0]) <= 0.005   # the servo lags
    assert all(abs(f.error.positions[0]) > 0.005 for f in listener.feedback
               if 0.05 <= f.time < ended.time)


def test_a_goal_out_of_reach_aborts_after_goal_time_and_holds(rig):
    listener = rig.start(request((0.05, [0.4]), goal=[JointTolerance('hip', 1e-6)],
                                 goal_time=0.1))
    rig.run(0.5)
    outcome = listener.outcome
    assert outcome.error_code is ErrorCode.GOAL_TOLERANCE_VIOLATED
    assert listener.feedback[-1].time == pytest.approx(0.16, abs=1e-9)   # first past 0.15
    held = rig.runtime.sim.commands.sample(rig.runtime.sim.time).positions
    np.testing.assert_array_equal(held, listener.feedback[-1].actual.positions)


def test_a_path_tolerance_aborts_and_the_joints_hold_where_they_are(rig):
    listener = rig.start(request((0.3, [0.6]), path=[JointTolerance('hip', 0.02)]))
    rig.run(0.5)
    outcome = listener.outcome
    assert outcome.error_code is ErrorCode.PATH_TOLERANCE_VIOLATED and 'hip' in outcome.message
    assert rig.warnings[-1] == (f'{topics.FOLLOW_JOINT_TRAJECTORY} goal aborted '
                                f'(PATH_TOLERANCE_VIOLATED): {outcome.message}')
    last = listener.feedback[-1]
    assert abs(last.error.positions[0]) > 0.02 and last.time < 0.3
    assert all(abs(f.error.positions[0]) <= 0.02 for f in listener.feedback[:-1])
    assert rig.positions[0] == pytest.approx(last.actual.positions[0], abs=0.01)
    assert rig.positions[0] < 0.5


def test_a_new_goal_or_command_preempts_the_goal(rig):
    first = rig.start(request((1.0, [0.5])))
    rig.run(0.1)
    second = rig.start(request((1.0, [-0.5])))
    assert first.outcome.state is GoalState.ABORTED
    assert first.outcome.error_code is ErrorCode.INVALID_GOAL
    assert topics.FOLLOW_JOINT_TRAJECTORY in first.outcome.message
    rig.run(0.1)
    count = len(first.feedback)
    assert count > 0 and len(second.feedback) > 0
    rig.runtime.on_positions(position_array([0.1, 0.1]))
    assert topics.POSITION_COMMANDS in second.outcome.message
    rig.run(0.1)
    assert len(first.feedback) == count and first.outcomes == [first.outcome]


def test_cancel_is_served_at_the_next_tick_even_when_paused(rig):
    listener = rig.start(request((1.0, [0.8])))
    rig.run(0.2)
    rig.runtime.pause(True)
    listener.cancel = True
    rig.runtime.tick()
    assert listener.outcome.state is GoalState.CANCELED
    held = rig.runtime.sim.commands.sample(rig.runtime.sim.time).positions
    np.testing.assert_array_equal(held, rig.positions)   # holds the position last published
    rig.runtime.pause(False)
    rig.run(0.3)
    assert rig.positions[0] == pytest.approx(held[0], abs=0.01)


def test_reset_aborts_the_goal(rig):
    listener = rig.start(request((1.0, [0.8])))
    rig.run(0.1)
    rig.runtime.reset()
    assert listener.outcome.error_code is ErrorCode.INVALID_GOAL
    assert 'reset' in listener.outcome.message


def test_bad_goals_are_refused_with_the_reason_and_counted(rig):
    runtime = rig.runtime
    problem = runtime.goal_problem(goal_msg(request((0.1, [0.2]), names=('ankle',))))
    assert 'ankle' in problem and rig.warnings and 'ankle' in rig.warnings[-1]
    problem = runtime.goal_problem(goal_msg(request((0.1, [0.2]),
                                                    goal=[JointTolerance('hip', -3.0)])))
    assert 'goal_tolerance of hip' in problem
    assert runtime.rejections == {'unknown_joint': 1, 'goal': 1}
    assert runtime.goal_problem(object()).startswith('not a FollowJointTrajectory goal')


def test_the_controller_name_names_the_topic_and_the_action(rig_scene):
    """A stack whose controller has another name (the action's name cannot be remapped in
    ROS 2 Jazzy): warnings and outcomes name its topic and action."""
    rig = Rig(rig_scene, trajectory_controller='/left/leg_controller')
    assert rig.runtime.trajectory_topic == '/left/leg_controller/joint_trajectory'
    assert rig.runtime.trajectory_action == '/left/leg_controller/follow_joint_trajectory'
    first = rig.start(request((1.0, [0.5])))
    rig.start(request((1.0, [0.4])))
    assert first.outcome.message == ('preempted by a new command on '
                                     '/left/leg_controller/follow_joint_trajectory')
    rig.runtime.goal_problem(goal_msg(request((0.1, [0.2]), names=('ankle',))))
    assert rig.warnings[-1].startswith('rejected command on '
                                       '/left/leg_controller/follow_joint_trajectory: ')
    with pytest.raises(ValueError, match='trajectory_controller'):
        Rig(rig_scene, trajectory_controller='leg controller')
    spaced = Rig(rig_scene, namespace='/go2')                   # the node's namespace
    spaced.runtime.on_positions(position_array([0.1]))
    spaced.start(request((1.0, [0.5])))
    spaced.runtime.reset()
    assert spaced.warnings[0].startswith('rejected command on '
                                         '/go2/forward_position_controller/commands: ')
    assert spaced.warnings[1].startswith('/go2/joint_trajectory_controller/'
                                         'follow_joint_trajectory goal aborted (INVALID_GOAL)')


def test_a_goal_that_ended_before_it_started_is_aborted_at_once(rig):
    """Stamped in sim time: accepted while it could still run, started after its end."""
    rig.run(0.1)
    msg = goal_msg(request((0.05, [0.2]), start=0.12))
    assert rig.runtime.goal_problem(msg) is None
    rig.run(0.1)
    listener = Listener()
    rig.runtime.start_goal(msg, listener)
    assert listener.outcome.error_code is ErrorCode.OLD_HEADER_TIMESTAMP
    assert listener.outcome.state is GoalState.ABORTED


# --- messages -------------------------------------------------------------------------------

def test_goal_messages_read_back_as_the_request():
    req = request((0.1, [0.2, 0.3]), (0.25, [0.1, -0.4]), names=('knee', 'hip'), start=1.5,
                  path=[JointTolerance('hip', 0.1, 0.5)],
                  goal=[JointTolerance('knee', 0.01, -1.0, 0.0)], goal_time=0.25)
    msg = goal_msg(req)
    raw = FACTORY.typestore.serialize_cdr(msg, msg.__msgtype__)
    back = inbound.follow_goal(FACTORY.typestore.deserialize_cdr(raw, msg.__msgtype__))
    assert back.path_tolerance == tuple(req.path_tolerance)
    assert back.goal_tolerance == tuple(req.goal_tolerance)
    assert back.goal_time_tolerance == 0.25 and back.multi_dof_joints == 0
    assert back.trajectory.start_time == 1.5 and back.trajectory.joint_names == ('knee', 'hip')
    assert [p.time_from_start for p in back.trajectory.points] == [0.1, 0.25]
    assert back.trajectory.points[1].positions == [0.1, -0.4]


def test_feedback_and_result_messages_fill_every_field():
    feedback = goals.GoalFeedback(time=2.5, joint_names=JOINTS,
                                  desired=targets(0.1, 0.2, velocities=(1.0, 2.0)),
                                  actual=targets(0.05, 0.25, velocities=(0.5, 2.5)),
                                  error=targets(0.05, -0.05, velocities=(0.5, -0.5)),
                                  time_from_start=0.75)
    msg = follow_messages.feedback_message(FACTORY, feedback)
    raw = FACTORY.typestore.serialize_cdr(msg, msg.__msgtype__)
    back = FACTORY.typestore.deserialize_cdr(raw, msg.__msgtype__)
    assert messages_equal(back, msg)
    assert (back.header.stamp.sec, back.header.stamp.nanosec) == (2, 500_000_000)
    assert back.joint_names == list(JOINTS)
    assert back.error.positions.tolist() == [0.05, -0.05]
    assert back.actual.velocities.tolist() == [0.5, 2.5]
    assert (back.desired.time_from_start.sec, back.desired.time_from_start.nanosec) == \
        (0, 750_000_000)
    result = follow_messages.result_message(FACTORY, goals.aborted('the simulation was reset'))
    raw = FACTORY.typestore.serialize_cdr(result, result.__msgtype__)
    back = FACTORY.typestore.deserialize_cdr(raw, result.__msgtype__)
    assert back.error_code == result.INVALID_GOAL == -1
    assert back.error_string == 'the simulation was reset'
    for code in ErrorCode:
        assert getattr(result, code.name) == code.value       # control_msgs' constants
