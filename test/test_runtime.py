"""The ROS-free core of the rft_sim node: pacing of real steps, publishing decisions,
command dispatch (malformed input never crashes or moves a joint), parameters, services and
divergence handling, on a real small scene with a fake wall clock."""
import types

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rft_sim_ros.ros import messages, topics
from rft_sim_ros.ros.bag import bag_topics, read_messages
from rft_sim_ros.ros.bag import BagWriter
from rft_sim_ros.ros.factory import RosbagsFactory
from rft_sim_ros.ros.runtime import SimRuntime, array_order
from rft_sim_ros.control.commands import TrajectoryCommand, TrajectoryPoint
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation
from ros_test_support import SERVO_RIG, FakeClock, Harness, position_array

FACTORY = RosbagsFactory()
PERIOD = 0.01  # s: the servo rig publishes at 100 Hz of sim time


@pytest.fixture(scope='module')
def rig_scene():
    return load_scene(SERVO_RIG)


@pytest.fixture
def rig(rig_scene):
    return Harness(rig_scene)


def trajectory(names, *points, start=0.0):
    """A rosbags JointTrajectory; points: (time_from_start, positions[, velocities])."""
    return messages.joint_trajectory_message(FACTORY, TrajectoryCommand(
        joint_names=names, start_time=start,
        points=[TrajectoryPoint(positions=p[1], time_from_start=p[0],
                                velocities=p[2] if len(p) > 2 else None) for p in points]))


# --- pacing and publishing ------------------------------------------------------------------

def test_first_tick_publishes_the_initial_state_and_diagnostics(rig):
    rig.runtime.tick()
    assert rig.times() == [0.0]
    assert rig.sink.states[0].joint_names == ('hip', 'knee')
    state, status = rig.sink.diagnostics[0]
    assert state is rig.sink.states[0] and status.stable and not status.paused
    assert status.scene == 'servo_rig'


def test_real_time_publishes_one_state_per_publish_period_of_wall_time(rig):
    rig.runtime.tick()
    rig.run(0.2)
    times = rig.times()
    assert len(times) == 1 + 20
    np.testing.assert_allclose(np.diff(times), PERIOD, rtol=1e-9)
    assert rig.sim.time == pytest.approx(0.2)


def test_real_time_factor_scales_sim_time(rig_scene):
    h = Harness(rig_scene, real_time_factor=0.5)
    h.run(0.2)
    assert h.sim.time == pytest.approx(0.1)
    assert h.runtime.tick_period == pytest.approx(0.01)


def test_as_fast_as_possible_steps_until_the_tick_budget(rig_scene):
    h = Harness(rig_scene, real_time_factor=0.0, tick_budget_s=0.05)
    h.clock.per_call = 0.01  # every clock read costs 10 ms of wall time
    h.runtime.tick()
    assert 4 <= len(h.times()) - 1 <= 6   # about budget / cost cycles, then back to ROS
    before = len(h.times())
    h.runtime.tick()
    assert len(h.times()) > before


def test_commands_are_taken_before_every_cycle_of_a_tick(rig_scene):
    """As fast as possible a tick runs many cycles; the node's command subscriptions are
    read before each (`take_commands`), so a command that came in during the third cycle
    holds from the fourth on, not from the tick after."""
    h = Harness(rig_scene, real_time_factor=0.0, tick_budget_s=0.05)
    h.clock.per_call = 0.005  # every clock read costs 5 ms of wall time: ~10 cycles a tick
    h.runtime.tick()
    targets = h.targets()
    targets[0] += 0.2
    taken = []

    def take_commands():
        taken.append(len(h.times()))
        if len(taken) == 4:  # (before the fourth cycle: three ran)
            assert h.runtime.on_positions(position_array(targets)).accepted
    before = len(h.times())
    h.runtime.tick(take_commands)
    assert len(h.times()) - before == len(taken) > 5  # once before each cycle
    assert taken[3] == before + 3
    np.testing.assert_allclose(h.targets(), targets)


def test_a_slow_machine_does_not_sprint_to_catch_up(rig):
    rig.runtime.tick()
    rig.clock.advance(30.0)            # e.g. the process was stopped for 30 s
    rig.runtime.tick()
    assert rig.times() == pytest.approx([0.0, PERIOD])


def test_changing_the_real_time_factor_applies_at_once(rig):
    rig.runtime.tick()
    rig.runtime.set_parameter('real_time_factor', 2.0)
    rig.run(0.1)
    assert rig.sim.time == pytest.approx(0.2)
    assert rig.runtime.real_time_factor == 2.0


def test_publish_rate_is_exact_on_average_with_stamps_on_whole_steps(rig_scene):
    h = Harness(rig_scene, publish_rate=300.0)   # 1 ms steps: 3.33 per period
    assert h.runtime.publish_period == pytest.approx(1 / 300)
    h.run(0.2)
    times = np.array(h.times())
    steps = np.round(times / h.sim.timestep)
    assert np.allclose(times, steps * h.sim.timestep, atol=1e-12)        # on whole steps
    assert set(np.diff(steps)) == {3, 4}
    n = len(times) - 1                                                   # cycles after t = 0
    assert n > 30 and abs(times[-1] - n / 300) <= 0.5 * h.sim.timestep   # the asked rate
    with pytest.raises(ValueError, match='publish_rate'):
        Harness(rig_scene, publish_rate=0.0)


def test_plates_are_published_only_when_asked(rig_scene):
    h = Harness(rig_scene, plates=True)
    h.runtime.tick()
    assert h.sink.states[0].active_plates is not None
    plain = Harness(rig_scene)
    plain.runtime.tick()
    assert plain.sink.states[0].active_plates is None


def test_diagnostics_every_wall_second_and_at_once_on_change(rig):
    rig.run(2.5)
    stamps = [state.time for state, _ in rig.sink.diagnostics]
    assert len(stamps) == 3             # t = 0, after 1 s and after 2 s of wall time
    assert all(status.real_time_factor == pytest.approx(1.0, abs=0.02)
               for _, status in rig.sink.diagnostics[1:])
    rig.runtime.set_parameter('zeta', 1.5)
    rig.run(0.01)
    state, status = rig.sink.diagnostics[-1]
    assert len(rig.sink.diagnostics) == 4 and state.zeta == 1.5


# --- parameters -----------------------------------------------------------------------------

def test_zeta_parameter_takes_effect_on_the_next_step(rig):
    assert rig.runtime.parameter_problem('zeta', 2.0) is None
    rig.runtime.set_parameter('zeta', 2.0)
    assert rig.sim.zeta == 2.0
    rig.run(0.01)
    assert rig.sink.states[-1].zeta == 2.0


@pytest.mark.parametrize('name, value, words', [
    ('zeta', -1.0, '> 0'), ('zeta', float('nan'), 'finite'), ('zeta', 1e3, '<= 100'),
    ('real_time_factor', -2.0, '>= 0'), ('paused', 'yes', 'true or false'),
    ('scene', 'plate_drop', 'read-only'), ('publish_rate', 10.0, 'read-only')])
def test_refused_parameters_leave_the_simulation_alone(rig, name, value, words):
    problem = rig.runtime.parameter_problem(name, value)
    assert problem and words in problem
    assert rig.sim.zeta == 0.5 and rig.runtime.real_time_factor == 1.0


def test_static_parameters_cannot_be_applied(rig):
    with pytest.raises(KeyError, match='publish_rate'):
        rig.runtime.set_parameter('publish_rate', 50.0)


# --- commands -------------------------------------------------------------------------------

def test_a_trajectory_moves_a_joint(rig):
    rig.runtime.tick()
    result = rig.runtime.on_trajectory(trajectory(['hip'], (0.1, [0.4])))
    assert result.accepted
    rig.run(0.6)
    hip, knee = rig.sink.states[-1].joint_positions
    assert hip == pytest.approx(0.4, abs=0.01) and knee == pytest.approx(0.0, abs=0.01)


def test_position_arrays_follow_the_joint_names_parameter(rig_scene):
    h = Harness(rig_scene, joint_names=['knee', 'hip'])
    assert h.runtime.on_positions(position_array([-0.3, 0.2])).accepted
    np.testing.assert_allclose(h.targets(), [0.2, -0.3])   # servo order: hip, knee
    h.run(0.5)
    np.testing.assert_allclose(h.sink.states[-1].joint_positions, [0.2, -0.3], atol=0.01)


def test_effort_arrays_drive_the_joints_until_a_position_command(rig_scene):
    """/effort_controller/commands (a Float64MultiArray as rosbags reads it from a bag or
    DDS): efforts in joint_names order replace the position servos until a position command;
    a malformed one is rejected with the reason and changes nothing."""
    h = Harness(rig_scene, joint_names=['knee', 'hip'])
    h.runtime.tick()
    result = h.runtime.on_efforts(position_array([0.3]))
    assert not result.accepted and result.reason.value == 'array_length'
    assert topics.EFFORT_COMMANDS in h.warnings[0]
    assert h.runtime.on_efforts(position_array([0.0, 0.3])).accepted  # knee 0, hip 0.3 N m
    assert h.runtime.sim.commands.efforts.tolist() == [0.3, 0.0]      # servo order
    h.run(0.4)
    hip, knee = h.sink.states[-1].joint_positions
    assert hip > 0.08                           # the torque turns the hip; no servo holds it
    assert h.sink.states[-1].joint_efforts[0] == pytest.approx(0.3)
    assert h.runtime.on_positions(position_array([0.0, 0.0])).accepted
    h.run(0.5)
    np.testing.assert_allclose(h.sink.states[-1].joint_positions, 0.0, atol=0.01)


def test_velocity_arrays_turn_the_joints_at_the_commanded_speed(rig_scene):
    """/velocity_controller/commands: velocities in joint_names order; the servos follow
    targets that move at them, so the joints turn at that speed; a bad one is rejected."""
    h = Harness(rig_scene, joint_names=['knee', 'hip'])
    h.runtime.tick()
    result = h.runtime.on_velocities(position_array([0.5]))
    assert not result.accepted and result.reason.value == 'array_length'
    assert topics.VELOCITY_COMMANDS in h.warnings[0]
    assert h.runtime.on_velocities(position_array([0.0, 0.5])).accepted   # hip 0.5 rad/s
    h.run(0.5)
    speeds = [s.joint_velocities[0] for s in h.sink.states if s.time > 0.25]
    assert np.mean(speeds) == pytest.approx(0.5, rel=0.02)
    hip, knee = h.sink.states[-1].joint_positions
    assert hip == pytest.approx(0.25, abs=0.03) and knee == pytest.approx(0.0, abs=0.01)
    assert h.runtime.on_positions(position_array([0.0, 0.0])).accepted
    h.run(0.5)
    np.testing.assert_allclose(h.sink.states[-1].joint_positions, 0.0, atol=0.01)


def test_joint_names_must_name_every_servo_once(rig_scene):
    for bad in (['hip'], ['hip', 'hip'], ['hip', 'knee', 'ankle'], ['hip', 'elbow']):
        with pytest.raises(ValueError, match='joint_names'):
            Harness(rig_scene, joint_names=bad)
    assert array_order(('a', 'b', 'c'), ('c', 'a', 'b')) == (1, 2, 0)


BAD_COMMANDS = [
    ('trajectory', lambda: trajectory(['ankle'], (0.1, [0.4])), 'unknown_joint', 'ankle'),
    ('trajectory', lambda: trajectory(['hip'], (0.1, [float('nan')])), 'not_finite', 'hip'),
    ('trajectory', lambda: trajectory(['hip', 'knee'], (0.1, [0.4])), 'positions_length',
     '1 positions for 2 joints'),
    ('trajectory', lambda: trajectory(['hip'], (0.2, [0.4]), (0.1, [0.3])),
     'time_not_increasing', 'not after'),
    ('trajectory', lambda: trajectory(['hip', 'hip'], (0.1, [0.4, 0.4])), 'duplicate_joint',
     'hip'),
    ('trajectory', lambda: trajectory(['hip'], start=1.0), 'empty', 'no points'),
    ('trajectory', lambda: None, 'malformed', 'not a joint trajectory'),
    ('trajectory', lambda: 'hip=0.4', 'malformed', 'not a joint trajectory'),
    ('positions', lambda: position_array([0.1]), 'array_length', '1 values, expected 2'),
    ('positions', lambda: position_array([0.1, float('inf')]), 'not_finite', 'knee'),
    ('positions', lambda: None, 'malformed', 'not a position array'),
    ('positions', lambda: types.SimpleNamespace(data=['a', 'b']), 'malformed', 'numbers'),
]


@pytest.mark.parametrize('kind, make, reason, words', BAD_COMMANDS)
def test_bad_commands_are_rejected_named_counted_and_move_nothing(rig, kind, make, reason,
                                                                  words):
    rig.runtime.tick()
    before = rig.targets()
    handler = rig.runtime.on_trajectory if kind == 'trajectory' else rig.runtime.on_positions
    result = handler(make())
    assert not result.accepted and result.reason.value == reason and words in result.message
    assert rig.runtime.rejections == {reason: 1}
    np.testing.assert_array_equal(rig.targets(), before)
    topic = topics.JOINT_TRAJECTORY if kind == 'trajectory' else topics.POSITION_COMMANDS
    assert len(rig.warnings) == 1 and topic in rig.warnings[0] and words in rig.warnings[0]
    rig.run(1.1)  # the next periodic /diagnostics counts it
    np.testing.assert_allclose(rig.sink.states[-1].joint_positions, 0.0, atol=1e-3)
    assert rig.sink.diagnostics[-1][1].commands_rejected == {reason: 1}


def test_rejection_warnings_are_throttled_but_all_counted(rig):
    for _ in range(50):
        rig.runtime.on_trajectory(trajectory(['ankle'], (0.1, [0.4])))
        rig.runtime.on_positions(position_array([1.0]))
    assert len(rig.warnings) == 2          # one line per topic and reason
    assert rig.runtime.rejections == {'unknown_joint': 50, 'array_length': 50}
    rig.clock.advance(5.0)
    rig.runtime.on_positions(position_array([1.0]))
    assert len(rig.warnings) == 3 and '49 similar suppressed' in rig.warnings[-1]


_anything = st.recursive(
    st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=3), max_leaves=6)


@settings(max_examples=150)
@given(names=_anything, positions=_anything, velocities=_anything, stamp=_anything,
       offset=_anything, data=_anything)
def test_arbitrary_messages_never_raise_and_bad_ones_move_nothing(rig_scene, names, positions,
                                                                  velocities, stamp, offset,
                                                                  data):
    h = Harness(rig_scene)
    before = h.targets()
    time_msg = types.SimpleNamespace(sec=stamp, nanosec=0)
    point = types.SimpleNamespace(positions=positions, velocities=velocities,
                                  time_from_start=types.SimpleNamespace(sec=offset, nanosec=0))
    message = types.SimpleNamespace(joint_names=names, points=[point],
                                    header=types.SimpleNamespace(stamp=time_msg))
    for send in (lambda: h.runtime.on_trajectory(message),
                 lambda: h.runtime.on_positions(types.SimpleNamespace(data=data))):
        result = send()  # (one at a time: each rejected one is checked before the next)
        if not result.accepted:
            np.testing.assert_array_equal(h.targets(), before)
        before = h.targets()


def test_a_scene_without_servos_rejects_commands(tmp_path):
    h = Harness(load_scene('plate_press'))
    assert h.runtime.joint_names == ()
    assert not h.runtime.on_trajectory(trajectory(['press'], (0.1, [0.0]))).accepted
    assert not h.runtime.on_positions(position_array([0.0])).accepted
    assert h.runtime.rejections == {'unknown_joint': 1, 'array_length': 1}
    assert any('no position servos' in w for w in h.warnings)


# --- services -------------------------------------------------------------------------------

def test_pause_stops_time_and_resuming_does_not_burst(rig):
    rig.run(0.1)
    result = rig.runtime.pause(True)
    assert result.success and 'paused' in result.message and rig.runtime.paused
    published = len(rig.times())
    rig.run(1.5)
    assert len(rig.times()) == published
    _, status = rig.sink.diagnostics[-1]
    assert status.paused and status.real_time_factor == 0.0
    assert rig.runtime.pause(False).success and not rig.runtime.paused
    rig.runtime.tick()
    assert len(rig.times()) == published  # re-anchored: nothing owed for the pause
    rig.run(0.05)
    assert len(rig.times()) == published + 5


def test_paused_parameter_pauses_like_the_service(rig_scene):
    h = Harness(rig_scene, paused=True)
    h.run(0.2)
    assert h.times() == [0.0]
    h.runtime.set_parameter('paused', False)
    h.run(0.1)
    assert len(h.times()) == 11


def test_step_advances_one_publish_period_while_paused(rig):
    rig.run(0.05)
    refused = rig.runtime.step()
    assert not refused.success and 'pause' in refused.message
    rig.runtime.pause(True)
    before = rig.times()
    result = rig.runtime.step()
    assert result.success and '0.060000' in result.message
    assert rig.times() == pytest.approx(before + [before[-1] + PERIOD])
    assert rig.runtime.paused


def test_reset_restores_the_scene_and_keeps_time_running(rig):
    rig.runtime.tick()
    rig.runtime.on_positions(position_array([0.5, -0.5]))
    rig.runtime.on_positions(position_array([0.5]))
    rig.run(0.5)
    assert rig.sink.states[-1].joint_positions[0] == pytest.approx(0.5, abs=0.02)
    result = rig.runtime.reset()
    assert result.success and 'running' in result.message
    np.testing.assert_array_equal(rig.targets(), [0.0, 0.0])   # commands dropped
    rig.run(0.05)
    times = rig.times()
    assert all(b > a for a, b in zip(times, times[1:]))         # sim time never goes back
    assert times[-1] == pytest.approx(0.55)
    assert abs(rig.sink.states[-1].joint_positions[0]) < 0.05
    assert rig.runtime.rejections == {'array_length': 1}        # kept across the reset


def test_reset_keeps_paused(rig):
    rig.runtime.pause(True)
    assert 'paused' in rig.runtime.reset().message and rig.runtime.paused


# --- divergence -----------------------------------------------------------------------------

def blow_up(sim):
    sim.data.qvel[:] = 1e5  # rad/s: caught as a runaway, or by MuJoCo's own reset


def test_divergence_pauses_reports_and_publishes_no_garbage(rig):
    rig.run(0.05)
    published = len(rig.times())
    blow_up(rig.sim)
    rig.run(0.1)
    assert rig.runtime.paused and rig.runtime.diverged
    assert len(rig.times()) == published           # the failed cycle is not published
    assert all(np.all(np.isfinite(s.joint_velocities)) for s in rig.sink.states)
    error = rig.errors[0]
    assert len(rig.errors) == 1 and 'diverged' in error
    assert 'runaway' in error or 'unstable' in error
    _, status = rig.sink.diagnostics[-1]
    assert not status.stable and ('runaway' in status.problem or 'unstable' in status.problem)
    # the only way on is a reset
    assert not rig.runtime.pause(False).success
    assert 'reset' in rig.runtime.parameter_problem('paused', False)
    assert not rig.runtime.step().success
    assert rig.runtime.reset().success and rig.runtime.diverged is None
    assert rig.runtime.paused                       # still paused until asked to run
    assert rig.runtime.parameter_problem('paused', False) is None
    rig.runtime.set_parameter('paused', False)
    rig.run(0.05)
    assert len(rig.times()) == published + 5
    assert rig.sink.diagnostics[-1][1].stable


def test_divergence_during_a_step_service_is_reported(rig):
    rig.runtime.tick()
    rig.runtime.pause(True)
    blow_up(rig.sim)
    result = rig.runtime.step()
    assert not result.success and 'diverged' in result.message
    rig.runtime.tick()
    assert not rig.sink.diagnostics[-1][1].stable


# --- the same sink interface as the bag writer ----------------------------------------------

def test_a_bag_writer_records_what_the_runtime_publishes(rig_scene, tmp_path):
    sim = Simulation(rig_scene)
    clock = FakeClock()
    with BagWriter(tmp_path / 'bag', list(rig_scene.legs)) as writer:
        runtime = SimRuntime(sim, writer, publish_rate=100.0, clock=clock)
        for _ in range(20):
            clock.advance(0.005)
            runtime.tick()
    recorded = bag_topics(tmp_path / 'bag')
    assert set(recorded) == set(topics.published_topics(['leg'], plates=False))
    assert recorded[topics.CLOCK].count == 11 and recorded[topics.DIAGNOSTICS].count == 1
    clocks = [m.clock.sec + m.clock.nanosec * 1e-9
              for _, _, m in read_messages(tmp_path / 'bag', [topics.CLOCK])]
    np.testing.assert_allclose(clocks, np.arange(11) * PERIOD, atol=1e-9)
