"""Servo command handling: trajectory interpolation and replacement as in ros2_control's
joint_trajectory_controller, array commands, rejection of bad input, throttled logging and
reading the ROS command messages."""
import copy
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rft_sim_ros.ros import inbound
from rft_sim_ros.ros.factory import RosbagsFactory, jazzy_typestore
from rft_sim_ros.control.commands import (CommandHandler, CommandRejected, Reason,
                                      TrajectoryCommand, TrajectoryPoint)
from rft_sim_ros.control.throttle import ThrottledLog

JOINTS = ('a', 'b', 'c')
INITIAL = np.array([0.1, -0.2, 0.3])
PROBE_TIMES = (0.0, 0.5, 1.0, 1.7, 2.5, 4.0, 10.0, 100.0)


def handler():
    return CommandHandler(JOINTS, INITIAL)


def traj(names, *points, start=0.0):
    """points: (time_from_start, positions[, velocities])."""
    return TrajectoryCommand(
        joint_names=names,
        points=[TrajectoryPoint(positions=p[1], time_from_start=p[0],
                                velocities=p[2] if len(p) > 2 else None) for p in points],
        start_time=start)


def snapshot(h, now=3.0):
    """Targets of a copy of `h` sampled forward in time from `now` (sampling a handler
    starts due deferred trajectories, so the original is left untouched)."""
    probe = copy.deepcopy(h)
    return [probe.sample(t) for t in now + np.array([0.0, 0.5, 1.0, 1.99, 2.0, 2.5, 4.0, 97.0])]


def hermite_reference(t0, p0, v0, t1, p1, v1, t):
    """Position and velocity of the cubic through (t0, p0, v0) and (t1, p1, v1), solved as a
    linear system in monomials (independent of the implementation's basis functions)."""
    matrix = np.array([[1, t0, t0**2, t0**3], [0, 1, 2 * t0, 3 * t0**2],
                       [1, t1, t1**2, t1**3], [0, 1, 2 * t1, 3 * t1**2]])
    c = np.linalg.solve(matrix, [p0, v0, p1, v1])
    return (c[0] + c[1] * t + c[2] * t**2 + c[3] * t**3,
            c[1] + 2 * c[2] * t + 3 * c[3] * t**2)


# --- construction and holding ---------------------------------------------------------------

def test_initial_targets_are_held():
    h = handler()
    for t in PROBE_TIMES:
        positions, velocities = h.sample(t)
        np.testing.assert_array_equal(positions, INITIAL)
        np.testing.assert_array_equal(velocities, 0.0)


@pytest.mark.parametrize('names, initial', [
    ((), ()), (('a', 'a'), (0, 0)), (('a', 'b'), (0,)), (('a',), (float('nan'),))])
def test_bad_construction_is_refused(names, initial):
    with pytest.raises(ValueError):
        CommandHandler(names, initial)


def test_sample_returns_copies():
    h = handler()
    h.sample(0.0).positions[:] = 99.0
    np.testing.assert_array_equal(h.sample(0.0).positions, INITIAL)


# --- interpolation --------------------------------------------------------------------------

def test_linear_interpolation_from_current_target():
    h = handler()
    assert h.set_trajectory(traj(JOINTS, (1.0, [1, 2, 3]), (2.0, [3, 2, 1])), now=0.0).accepted
    # from the current target (t = 0) to point 0 (t = 1)
    p, v = h.sample(0.25)
    np.testing.assert_allclose(p, INITIAL + 0.25 * (np.array([1, 2, 3]) - INITIAL))
    np.testing.assert_allclose(v, np.array([1, 2, 3]) - INITIAL)
    # between point 0 and point 1
    p, v = h.sample(1.5)
    np.testing.assert_allclose(p, [2, 2, 2])
    np.testing.assert_allclose(v, [2, 0, -2])
    np.testing.assert_allclose(h.sample(1.0).positions, [1, 2, 3])


def test_cubic_interpolation_when_velocities_are_given():
    h = handler()
    points = [(1.0, [1.0, 0.0, 0.0], [0.5, -1.0, 0.0]), (3.0, [2.0, 1.0, -1.0], [0.0, 2.0, 0.3])]
    assert h.set_trajectory(traj(JOINTS, *points), now=0.0).accepted
    for t in (0.0, 0.3, 0.9, 1.0, 1.4, 2.2, 2.99):
        p, v = h.sample(t)
        if t < 1.0:   # from the held initial target (velocity 0) to point 0
            segment = (0.0, INITIAL, np.zeros(3), 1.0, points[0][1], points[0][2])
        else:
            segment = (1.0, points[0][1], points[0][2], 3.0, points[1][1], points[1][2])
        for j in range(3):
            ref_p, ref_v = hermite_reference(*[x if np.isscalar(x) else x[j] for x in segment],
                                             t)
            assert p[j] == pytest.approx(ref_p, abs=1e-12)
            assert v[j] == pytest.approx(ref_v, abs=1e-12)


def test_linear_segment_when_only_one_end_has_velocities():
    h = handler()
    h.set_trajectory(traj(JOINTS, (1.0, [1, 1, 1]), (2.0, [2, 2, 2], [5, 5, 5])), now=0.0)
    np.testing.assert_allclose(h.sample(1.5).positions, [1.5, 1.5, 1.5])


def test_last_point_is_held_after_the_end():
    h = handler()
    h.set_trajectory(traj(JOINTS, (1.0, [1, 2, 3], [1, 1, 1])), now=0.0)
    for t in (1.0, 1.5, 50.0):
        p, v = h.sample(t)
        np.testing.assert_array_equal(p, [1, 2, 3])
        np.testing.assert_array_equal(v, 0.0)


def test_first_point_at_time_zero_is_jumped_to():
    h = handler()
    h.set_trajectory(traj(JOINTS, (0.0, [1, 1, 1]), (1.0, [2, 2, 2])), now=5.0)
    np.testing.assert_array_equal(h.sample(5.0).positions, [1, 1, 1])
    np.testing.assert_allclose(h.sample(5.5).positions, [1.5, 1.5, 1.5])


def test_times_are_relative_to_receipt_when_start_is_zero():
    h = handler()
    h.set_trajectory(traj(JOINTS, (1.0, [1, 1, 1])), now=10.0)
    np.testing.assert_array_equal(h.sample(10.0).positions, INITIAL)
    np.testing.assert_array_equal(h.sample(11.0).positions, [1, 1, 1])


# --- replacement and start times ------------------------------------------------------------

def test_new_trajectory_replaces_the_active_one_from_the_current_target():
    h = handler()
    h.set_trajectory(traj(JOINTS, (2.0, [2, 2, 2]), (4.0, [0, 0, 0])), now=0.0)
    before = h.sample(1.0)
    h.set_trajectory(traj(JOINTS, (1.0, [5, 5, 5], [0, 0, 0])), now=1.0)
    after = h.sample(1.0)
    np.testing.assert_allclose(after.positions, before.positions)
    np.testing.assert_allclose(after.velocities, before.velocities)   # cubic keeps velocity
    np.testing.assert_allclose(h.sample(2.0).positions, [5, 5, 5])
    np.testing.assert_allclose(h.sample(3.5).positions, [5, 5, 5])    # old points are gone
    # the cubic starts with the old trajectory's velocity
    for t in (1.25, 1.5, 1.75):
        for j in range(3):
            ref, _ = hermite_reference(1.0, before.positions[j], before.velocities[j],
                                       2.0, 5.0, 0.0, t)
            assert h.sample(t).positions[j] == pytest.approx(ref, abs=1e-12)


def test_start_time_in_the_future_keeps_the_active_trajectory_until_then():
    h = handler()
    h.set_trajectory(traj(JOINTS, (4.0, [4, 4, 4])), now=0.0)
    old = CommandHandler(JOINTS, INITIAL)
    old.set_trajectory(traj(JOINTS, (4.0, [4, 4, 4])), now=0.0)
    assert h.set_trajectory(traj(JOINTS, (1.0, [0, 0, 0]), start=3.0), now=1.0).accepted
    for t in (1.0, 2.0, 2.999, 3.0):
        np.testing.assert_allclose(h.sample(t).positions, old.sample(t).positions)
    # from the start time (3 s) it goes linearly from the old target there to point 0 at 4 s
    at_start = old.sample(3.0).positions
    np.testing.assert_allclose(h.sample(3.5).positions, 0.5 * at_start)
    np.testing.assert_allclose(h.sample(4.0).positions, 0.0)


def test_start_handoff_does_not_depend_on_sampling_times():
    coarse, fine = handler(), handler()
    for h in (coarse, fine):
        h.set_trajectory(traj(JOINTS, (4.0, [4, 4, 4])), now=0.0)
        h.set_trajectory(traj(JOINTS, (1.0, [0, 0, 0]), start=2.0), now=0.5)
    for t in np.arange(0.5, 3.0, 0.01):
        fine.sample(t)
    np.testing.assert_allclose(coarse.sample(2.5).positions, fine.sample(2.5).positions)


def test_newer_deferred_trajectory_replaces_the_pending_one():
    h = handler()
    h.set_trajectory(traj(JOINTS, (1.0, [1, 1, 1]), start=5.0), now=0.0)
    h.set_trajectory(traj(JOINTS, (1.0, [2, 2, 2]), start=7.0), now=1.0)
    np.testing.assert_array_equal(h.sample(6.0).positions, INITIAL)
    np.testing.assert_array_equal(h.sample(8.0).positions, [2, 2, 2])


def test_immediate_command_cancels_a_pending_trajectory():
    h = handler()
    h.set_trajectory(traj(JOINTS, (1.0, [1, 1, 1]), start=5.0), now=0.0)
    h.set_trajectory(traj(JOINTS, (1.0, [2, 2, 2])), now=1.0)
    np.testing.assert_array_equal(h.sample(9.0).positions, [2, 2, 2])
    h.set_trajectory(traj(JOINTS, (1.0, [3, 3, 3]), start=12.0), now=10.0)
    assert h.set_positions([4, 4, 4], now=11.0).accepted
    np.testing.assert_array_equal(h.sample(20.0).positions, [4, 4, 4])


def test_start_in_the_past_drops_waypoints_already_passed():
    h = handler()
    command = traj(JOINTS, (1.0, [9, 9, 9]), (2.0, [2, 2, 2]), (3.0, [3, 3, 3]), start=0.5)
    assert h.set_trajectory(command, now=2.0).accepted
    np.testing.assert_array_equal(h.sample(2.0).positions, INITIAL)      # no jump
    np.testing.assert_allclose(h.sample(2.25).positions, (INITIAL + [2, 2, 2]) / 2)
    np.testing.assert_allclose(h.sample(2.5).positions, [2, 2, 2])
    np.testing.assert_allclose(h.sample(3.0).positions, [2.5, 2.5, 2.5])


def test_partial_trajectory_holds_the_other_joints():
    h = handler()
    h.set_trajectory(traj(JOINTS, (2.0, [2, 2, 2])), now=0.0)
    moving = h.sample(1.0).positions
    assert h.set_trajectory(traj(('c',), (1.0, [7.0])), now=1.0).accepted
    for t in (1.0, 1.5, 2.0, 5.0):
        np.testing.assert_allclose(h.sample(t).positions[:2], moving[:2])
    np.testing.assert_allclose(h.sample(2.0).positions[2], 7.0)


def test_joint_order_of_the_command_is_respected():
    h = handler()
    h.set_trajectory(traj(('c', 'a', 'b'), (1.0, [3.0, 1.0, 2.0])), now=0.0)
    np.testing.assert_array_equal(h.sample(1.0).positions, [1.0, 2.0, 3.0])


def test_array_command_sets_all_targets_and_cancels_the_trajectory():
    h = handler()
    h.set_trajectory(traj(JOINTS, (5.0, [5, 5, 5])), now=0.0)
    assert h.set_positions(np.array([1.0, 2.0, 3.0]), now=1.0).accepted
    for t in (1.0, 3.0, 10.0):
        np.testing.assert_array_equal(h.sample(t).positions, [1, 2, 3])
        np.testing.assert_array_equal(h.sample(t).velocities, 0.0)


def test_velocity_command_moves_the_targets_from_where_they_are():
    """A velocity forward controller's command: the targets move at the velocities from
    the targets they had, until a position command; a trajectory takes over from the moving
    target, velocity included (a cubic first segment where its waypoints carry velocities)."""
    h = handler()
    h.set_trajectory(traj(JOINTS, (2.0, [1.1, 0.8, 0.3])), now=0.0)
    at_one = h.sample(1.0).positions                         # halfway: 0.6, 0.3, 0.3
    velocities = np.array([0.5, -1.0, 0.0])
    assert h.set_velocities(velocities, now=1.0).accepted
    for t in (1.0, 1.5, 4.0):
        target = h.sample(t)
        np.testing.assert_allclose(target.positions, at_one + velocities * (t - 1.0))
        np.testing.assert_array_equal(target.velocities, velocities)
    h.set_trajectory(traj(JOINTS, (1.0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])), now=4.0)
    start = h.sample(4.0)
    np.testing.assert_allclose(start.positions, at_one + velocities * 3.0)
    np.testing.assert_allclose(start.velocities, velocities)   # continuous
    assert h.set_velocities([0.1, 0.2], now=4.5).reason is Reason.ARRAY_LENGTH
    assert h.set_velocities([0.1, math.nan, 0.0], now=4.5).reason is Reason.NOT_FINITE
    assert h.set_positions([0.0, 0.0, 0.0], now=6.0).accepted
    np.testing.assert_array_equal(h.sample(9.0).velocities, 0.0)


def test_velocity_command_ends_effort_mode_from_the_tracked_positions():
    h = handler()
    h.set_efforts([1.0, 1.0, 1.0], now=0.0)
    h.track(np.array([0.4, 0.5, 0.6]), now=1.0)
    assert h.set_velocities(np.array([1.0, 0.0, 0.0]), now=1.0).accepted
    assert h.efforts is None
    np.testing.assert_allclose(h.sample(2.0).positions, [1.4, 0.5, 0.6])


# --- rejection ------------------------------------------------------------------------------

GOOD_POINTS = ((0.5, [1, 1, 1], [0, 0, 0]), (1.0, [2, 2, 2]))
BAD_TRAJECTORIES = [
    (traj((), (1.0, [])), Reason.EMPTY, 'no joint names'),
    (traj(JOINTS), Reason.EMPTY, 'no points'),
    (traj(('a', 'x', 'y'), (1.0, [1, 1, 1])), Reason.UNKNOWN_JOINT, 'x, y'),
    (traj(('a', 'b', 'a'), (1.0, [1, 1, 1])), Reason.DUPLICATE_JOINT, 'a'),
    (traj(JOINTS, (1.0, [1, float('nan'), 1])), Reason.NOT_FINITE, 'b'),
    (traj(JOINTS, (1.0, [1, 1, 1], [0, 0, float('inf')])), Reason.NOT_FINITE, 'c'),
    (traj(JOINTS, (float('nan'), [1, 1, 1])), Reason.NOT_FINITE, 'time_from_start'),
    (traj(JOINTS, (1.0, [1, 1, 1]), start=float('inf')), Reason.NOT_FINITE, 'start time'),
    (traj(JOINTS, (-0.1, [1, 1, 1])), Reason.TIME_NEGATIVE, 'negative'),
    (traj(JOINTS, (1.0, [1, 1, 1]), start=-2.0), Reason.TIME_NEGATIVE, 'start time'),
    (traj(JOINTS, (1.0, [1, 1, 1]), (1.0, [2, 2, 2])), Reason.TIME_NOT_INCREASING, 'point 1'),
    (traj(JOINTS, (1.0, [1, 1, 1]), (0.5, [2, 2, 2])), Reason.TIME_NOT_INCREASING, 'point 1'),
    (traj(JOINTS, (1.0, [1, 1])), Reason.POSITIONS_LENGTH, '2 positions for 3 joints'),
    (traj(JOINTS, *GOOD_POINTS, (2.0, [1, 1, 1, 1])), Reason.POSITIONS_LENGTH, 'point 2'),
    (traj(JOINTS, (1.0, [1, 1, 1], [1, 1])), Reason.VELOCITIES_LENGTH, '2 velocities'),
    (traj(JOINTS, (1.0, [1, 1, 1]), start=1.0), Reason.ENDS_IN_PAST, 'before now'),
    (traj(JOINTS, (1.0, 'abc')), Reason.MALFORMED, 'positions'),
    (traj(JOINTS, (1.0, [[1, 1, 1]])), Reason.MALFORMED, 'positions'),
    (traj((1, 2, 3), (1.0, [1, 1, 1])), Reason.MALFORMED, 'strings'),
    (traj(JOINTS, (1.0, [1, 1, 1]), start='soon'), Reason.MALFORMED, 'start time'),
    (TrajectoryCommand(JOINTS, [None]), Reason.MALFORMED, 'point 0'),
    (TrajectoryCommand(JOINTS, 5), Reason.MALFORMED, 'trajectory'),
    ('not a trajectory', Reason.MALFORMED, 'trajectory'),
    (traj(JOINTS, (0.0, [1, 1, 1]), (1e-9, [2, 2, 2]), start=1e9), Reason.TIME_NOT_INCREASING,
     'too close'),
    (traj(JOINTS, (1e308, [1, 1, 1]), start=1e308), Reason.NOT_FINITE, 'end time'),
]


@pytest.fixture
def busy_handler():
    """A handler with an active trajectory and a pending one, at sim time 3 s."""
    h = handler()
    h.set_trajectory(traj(JOINTS, (2.0, [2, 2, 2], [0, 1, 0]), (6.0, [0, 1, 0])), now=0.0)
    h.set_trajectory(traj(('b',), (1.0, [5.0])), now=3.0)
    h.set_trajectory(traj(JOINTS, (2.0, [9, 9, 9]), start=5.0), now=3.0)
    return h


def test_a_velocity_commands_target_stops_at_the_joints_range_and_reverses_from_there():
    handler = CommandHandler(JOINTS, [0.0, 0.0, 0.0],
                             ranges=[[-1.0, 1.0], [-np.inf, np.inf], [-0.5, 0.5]])
    assert handler.set_velocities([1.0, 1.0, -1.0], now=0.0).accepted
    targets = handler.sample(3.0)  # (3 rad on: a and c at their stops, b free)
    assert targets.positions.tolist() == [1.0, 3.0, -0.5]
    assert targets.velocities.tolist() == [0.0, 1.0, 0.0]  # (stopped)
    assert handler.set_velocities([-1.0, 0.0, 1.0], now=3.0).accepted
    assert handler.sample(3.5).positions.tolist() == [0.5, 3.0, 0.0]  # (from the stops)


def test_a_passive_joint_named_in_a_command_is_said_to_be_passive():
    handler = CommandHandler(JOINTS, [0.0, 0.0, 0.0], passive_joint_names=('pin',))
    result = handler.set_trajectory(traj(('a', 'pin', 'x'), (1.0, [1, 1, 1])), now=0.0)
    assert result.reason is Reason.UNKNOWN_JOINT
    assert result.message.startswith("passive joint(s) pin (no command interfaces: the "
                                      "scene's servos can give them a servo); unknown "
                                      'joint(s) x; commanded joints: a, b, c')


@pytest.mark.parametrize('command, reason, detail', BAD_TRAJECTORIES)
def test_bad_trajectory_is_rejected_and_changes_nothing(busy_handler, command, reason, detail):
    before = snapshot(busy_handler)
    result = busy_handler.set_trajectory(command, now=3.0)
    assert not result.accepted
    assert result.reason is reason
    assert detail in result.message
    assert busy_handler.rejections == {reason.value: 1}
    after = snapshot(busy_handler)
    for (p0, v0), (p1, v1) in zip(before, after):
        np.testing.assert_array_equal(p0, p1)
        np.testing.assert_array_equal(v0, v1)


@pytest.mark.parametrize('positions, reason, detail', [
    ([1.0, 2.0], Reason.ARRAY_LENGTH, '2 values, expected 3 (a, b, c)'),
    ([1.0, 2.0, 3.0, 4.0], Reason.ARRAY_LENGTH, '4 values'),
    ([], Reason.ARRAY_LENGTH, '0 values'),
    ([1.0, float('-inf'), 3.0], Reason.NOT_FINITE, 'b'),
    ([[1.0, 2.0, 3.0]], Reason.MALFORMED, 'flat'),
    (None, Reason.MALFORMED, 'numbers'),
    (['1', '2', '3'], Reason.MALFORMED, 'numbers'),
    ([True, False, True], Reason.MALFORMED, 'numbers'),
    ([1.0, None, 2.0], Reason.MALFORMED, 'numbers'),
    ([[1.0], [2.0, 3.0]], Reason.MALFORMED, 'numbers'),
])
def test_bad_array_command_is_rejected_and_changes_nothing(busy_handler, positions, reason,
                                                           detail):
    before = snapshot(busy_handler)
    result = busy_handler.set_positions(positions, now=3.0)
    assert (result.accepted, result.reason) == (False, reason)
    assert detail in result.message
    assert busy_handler.rejections == {reason.value: 1}
    for (p0, v0), (p1, v1) in zip(before, snapshot(busy_handler)):
        np.testing.assert_array_equal(p0, p1)
        np.testing.assert_array_equal(v0, v1)


def test_check_raises_on_a_rejection_and_passes_an_acceptance():
    h = handler()
    with pytest.raises(CommandRejected, match=r'command rejected \(not_finite\): .*b') as caught:
        h.set_positions([1.0, math.nan, 3.0], now=0.0).check()
    assert isinstance(caught.value, ValueError)
    assert caught.value.result.reason is Reason.NOT_FINITE
    np.testing.assert_array_equal(h.sample(1.0).positions, INITIAL)   # nothing changed
    accepted = h.set_positions([1.0, 2.0, 3.0], now=0.0)
    assert accepted.check() is accepted
    np.testing.assert_array_equal(h.sample(1.0).positions, [1.0, 2.0, 3.0])


@settings(max_examples=300, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=0, max_size=5),
       st.sampled_from([np.float64, np.float32, np.int64, list]))
def test_array_commands_are_accepted_exactly_when_valid(values, kind):
    """Arrays as gaits and controllers hand them over each tick (float64 numpy arrays of one
    value per joint) and every other form: accepted exactly when there is one finite number
    per joint, huge ones included, and then held as given."""
    if kind is list:
        command = list(values)
    else:
        with np.errstate(all='ignore'):
            if kind is np.int64 and not all(math.isfinite(v) for v in values):
                return  # no integer form of a non-finite value
            command = np.array(values, dtype=kind) if kind is not np.int64 else np.array(
                [int(np.clip(v, -2**62, 2**62)) for v in values], dtype=kind)
    expected = np.array(command, dtype=float)
    h = handler()
    result = h.set_positions(command, now=1.0)
    valid = expected.shape == (3,) and bool(np.isfinite(expected).all())
    assert result.accepted == valid, result.message
    held = h.sample(2.0).positions
    np.testing.assert_array_equal(held, expected if valid else INITIAL)


def test_array_command_holds_a_copy_of_the_callers_array():
    h = handler()
    targets = np.array([1.0, 2.0, 3.0])
    assert h.set_positions(targets, now=0.0).accepted
    targets[:] = 7.0  # a gait reusing its buffer for the next tick
    np.testing.assert_array_equal(h.sample(1.0).positions, [1.0, 2.0, 3.0])
    huge = np.array([1e200, -1e300, 1.7e308])  # finite, though their squares overflow
    assert h.set_positions(huge, now=1.0).accepted
    np.testing.assert_array_equal(h.sample(1.0).positions, huge)
    assert h.set_positions(np.array([1e200, np.nan, 0.0]), now=1.0).reason is Reason.NOT_FINITE


def test_hold_positions_is_set_positions_without_the_checks():
    """A built-in gait's targets (hold_positions) act as the same position command: the
    same targets afterwards, pending trajectories and effort mode cancelled alike."""
    checked, unchecked = handler(), handler()
    for h in (checked, unchecked):
        h.set_trajectory(traj(JOINTS, (5.0, [5, 5, 5])), now=0.0)
        h.set_trajectory(traj(JOINTS, (1.0, [9, 9, 9]), start=4.0), now=1.0)
        h.set_efforts([0.5, 0.5, 0.5], now=1.5)
    assert checked.set_positions(np.array([1.0, 2.0, 3.0]), now=2.0).accepted
    unchecked.hold_positions(np.array([1.0, 2.0, 3.0]), now=2.0)
    assert checked.efforts is None and unchecked.efforts is None
    for t in (2.0, 4.5, 10.0):
        for a, b in zip(checked.sample(t), unchecked.sample(t)):
            np.testing.assert_array_equal(a, b)
    assert unchecked.rejections == {}


def test_rejections_are_counted_per_reason():
    h = handler()
    for _ in range(3):
        h.set_positions([1.0], now=0.0)
    h.set_trajectory(traj(('zz',), (1.0, [1.0])), now=0.0)
    assert h.set_positions([1.0, 2.0, 3.0], now=0.0).accepted
    assert h.rejections == {'array_length': 3, 'unknown_joint': 1}


# --- fuzzing --------------------------------------------------------------------------------

junk = st.one_of(st.none(), st.integers(), st.floats(), st.text(max_size=5),
                 st.lists(st.floats(), max_size=4), st.lists(st.text(max_size=3), max_size=4),
                 st.just(float('nan')), st.just(object()))


def _corrupt(draw, names, points, start):
    """Apply one random corruption that makes a valid trajectory invalid."""
    n = len(names)
    kind = draw(st.sampled_from([
        'no_names', 'no_points', 'unknown', 'duplicate', 'nan_position', 'nan_velocity',
        'negative_time', 'repeat_time', 'positions_length', 'velocities_length',
        'ends_in_past', 'junk_positions', 'junk_time', 'junk_names', 'nan_time',
        'negative_start']))
    i = draw(st.integers(0, len(points) - 1))
    points = [dict(p) for p in points]
    if kind == 'no_names':
        names = []
    elif kind == 'no_points':
        points = []
    elif kind == 'unknown':
        names = list(names)
        names[draw(st.integers(0, n - 1))] = draw(st.text(min_size=1, max_size=4).filter(
            lambda s: s not in JOINTS))
    elif kind == 'duplicate':
        names = list(names) + [names[0]]
        for p in points:
            p['positions'] = list(p['positions']) + [0.0]
            if p['velocities'] is not None:
                p['velocities'] = list(p['velocities']) + [0.0]
    elif kind == 'nan_position':
        points[i]['positions'] = list(points[i]['positions'])
        points[i]['positions'][draw(st.integers(0, n - 1))] = draw(
            st.sampled_from([math.nan, math.inf, -math.inf]))
    elif kind == 'nan_velocity':
        points[i]['velocities'] = [0.0] * n
        points[i]['velocities'][draw(st.integers(0, n - 1))] = math.nan
    elif kind == 'negative_time':
        points[0]['time_from_start'] = -draw(st.floats(1e-6, 10))
    elif kind == 'repeat_time':
        if len(points) < 2:
            points.append(dict(points[0]))
        points[-1]['time_from_start'] = points[-2]['time_from_start'] - draw(st.floats(0, 1))
    elif kind == 'positions_length':
        points[i]['positions'] = list(points[i]['positions']) + [0.0] * draw(st.integers(1, 3))
    elif kind == 'velocities_length':
        points[i]['velocities'] = [0.0] * draw(st.integers(1, 5).filter(lambda k: k != n))
    elif kind == 'ends_in_past':   # explicit start 0.5 s, ends by 0.51 s, received at 3 s
        start = 0.5
        points = [{**p, 'time_from_start': p['time_from_start'] * 1e-3} for p in points]
    elif kind == 'junk_positions':
        points[i]['positions'] = draw(junk.filter(
            lambda x: not (isinstance(x, list) and len(x) == n
                           and all(isinstance(v, float) and math.isfinite(v) for v in x))))
    elif kind == 'junk_time':
        points[i]['time_from_start'] = draw(st.one_of(st.none(), st.text(max_size=3),
                                                      st.lists(st.floats(), max_size=2)))
    elif kind == 'junk_names':
        names = draw(st.one_of(st.none(), st.integers(), st.lists(st.integers(), min_size=1)))
    elif kind == 'nan_time':
        points[i]['time_from_start'] = math.nan
    elif kind == 'negative_start':
        start = -draw(st.floats(1e-3, 1e3))
    return names, points, start


@st.composite
def malformed_trajectories(draw):
    if draw(st.booleans()):   # sometimes a completely foreign object
        return draw(junk)
    names = draw(st.lists(st.sampled_from(JOINTS), min_size=1, max_size=3, unique=True))
    n = len(names)
    gaps = draw(st.lists(st.floats(0.01, 2.0), min_size=1, max_size=4))
    with_velocities = draw(st.booleans())
    points = [{'positions': draw(st.lists(st.floats(-3, 3), min_size=n, max_size=n)),
               'velocities': ([0.1] * n if with_velocities else None),
               'time_from_start': float(t)}
              for t in np.cumsum(gaps)]
    names, points, start = _corrupt(draw, names, points, 0.0)
    return TrajectoryCommand(joint_names=names, points=[TrajectoryPoint(**p) for p in points],
                             start_time=start)


@settings(max_examples=400, deadline=None)
@given(st.data())
def test_fuzz_malformed_commands_never_raise_nor_change_targets(data):
    h = handler()
    h.set_trajectory(traj(JOINTS, (2.0, [2, 2, 2], [0, 1, 0]), (6.0, [0, 1, 0])), now=0.0)
    h.set_trajectory(traj(JOINTS, (2.0, [9, 9, 9]), start=5.0), now=3.0)
    before = snapshot(h)
    n_bad = data.draw(st.integers(1, 5))
    for _ in range(n_bad):
        if data.draw(st.booleans()):
            result = h.set_trajectory(data.draw(malformed_trajectories()), now=3.0)
        else:
            result = h.set_positions(data.draw(st.one_of(
                junk, st.lists(st.floats(), min_size=3, max_size=3)).filter(
                    lambda v: not (isinstance(v, list) and len(v) == 3 and all(
                        isinstance(x, float) and math.isfinite(x) for x in v)))), now=3.0)
        assert not result.accepted and result.reason is not None and result.message
    assert sum(h.rejections.values()) == n_bad
    for (p0, v0), (p1, v1) in zip(before, snapshot(h)):
        np.testing.assert_array_equal(p0, p1)
        np.testing.assert_array_equal(v0, v1)


@st.composite
def valid_trajectories(draw):
    names = draw(st.lists(st.sampled_from(JOINTS), min_size=1, max_size=3, unique=True))
    n = len(names)
    times = np.cumsum(draw(st.lists(st.floats(0.01, 2.0), min_size=1, max_size=5)))
    with_velocities = draw(st.booleans())
    points = [TrajectoryPoint(
        positions=draw(st.lists(st.floats(-3, 3), min_size=n, max_size=n)),
        velocities=(draw(st.lists(st.floats(-3, 3), min_size=n, max_size=n))
                    if with_velocities else None),
        time_from_start=float(t)) for t in times]
    return TrajectoryCommand(names, points)


@settings(max_examples=200, deadline=None)
@given(valid_trajectories(), st.floats(0, 100))
def test_valid_trajectories_pass_through_their_waypoints(command, now):
    h = handler()
    assert h.set_trajectory(command, now=now).accepted
    index = [JOINTS.index(n) for n in command.joint_names]
    others = [j for j in range(3) if j not in index]
    for point in command.points:
        t = now + point.time_from_start
        positions = h.sample(t).positions
        np.testing.assert_allclose(positions[index], point.positions, atol=1e-9)
        np.testing.assert_array_equal(positions[others], INITIAL[others])
    end = now + command.points[-1].time_from_start
    np.testing.assert_allclose(h.sample(end + 1.0).positions[index],
                               command.points[-1].positions, atol=1e-9)


# --- throttled log --------------------------------------------------------------------------

class ManualClock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_throttled_log_passes_one_line_per_key_per_period():
    lines, clock = [], ManualClock()
    log = ThrottledLog(lines.append, period_s=5.0, clock=clock)
    assert log('unknown_joint', 'unknown joint x')
    clock.now = 1.0
    assert not log('unknown_joint', 'unknown joint y')
    assert log('not_finite', 'nan in b')            # other keys are independent
    clock.now = 4.9
    assert not log('unknown_joint', 'unknown joint z')
    clock.now = 5.0
    assert log('unknown_joint', 'unknown joint w')
    clock.now = 5.5
    assert not log('not_finite', 'nan in c')        # 4.5 s after its last line
    assert lines == ['unknown joint x', 'nan in b',
                     'unknown joint w (2 similar suppressed)']


def test_throttled_log_with_rejections_from_the_handler():
    lines, clock = [], ManualClock()
    log = ThrottledLog(lines.append, period_s=1.0, clock=clock)
    h = handler()
    for step in range(100):                          # a 100 Hz stream of bad commands for 1 s
        clock.now = step * 0.01
        result = h.set_positions([1.0, 2.0], now=clock.now)
        log(result.reason, f'/forward_position_controller/commands: {result.message}')
    clock.now = 1.0
    result = h.set_positions([1.0, 2.0], now=clock.now)
    log(result.reason, f'/forward_position_controller/commands: {result.message}')
    assert len(lines) == 2
    assert 'expected 3' in lines[0] and lines[1].endswith('(99 similar suppressed)')


def test_throttled_log_refuses_a_negative_period():
    with pytest.raises(ValueError):
        ThrottledLog(print, period_s=-1.0)


# --- incoming ROS messages (Jazzy definitions, CDR round trip) ------------------------------

TS = jazzy_typestore()
F = RosbagsFactory(TS)


def received(msg):
    """What a subscriber would get: the message after CDR serialisation."""
    return TS.deserialize_cdr(TS.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)


def ros_trajectory(names, points, stamp=(0, 0)):
    def point(positions, velocities, sec, nanosec):
        return F.make('trajectory_msgs/msg/JointTrajectoryPoint',
                      positions=F.float64_sequence(positions),
                      velocities=F.float64_sequence(velocities),
                      accelerations=F.float64_sequence([]), effort=F.float64_sequence([]),
                      time_from_start=F.make('builtin_interfaces/msg/Duration', sec=sec,
                                             nanosec=nanosec))
    header = F.make('std_msgs/msg/Header', frame_id='',
                    stamp=F.make('builtin_interfaces/msg/Time', sec=stamp[0], nanosec=stamp[1]))
    return received(F.make('trajectory_msgs/msg/JointTrajectory', header=header,
                           joint_names=list(names), points=[point(*p) for p in points]))


def test_joint_trajectory_message_drives_the_handler():
    msg = ros_trajectory(('b', 'a'), [([1.0, 2.0], [], 0, 500_000_000),
                                      ([3.0, 4.0], [0.5, 0.5], 1, 0)], stamp=(2, 250_000_000))
    command = inbound.trajectory_command(msg)
    assert command.joint_names == ('b', 'a')
    assert command.start_time == pytest.approx(2.25)
    assert [p.time_from_start for p in command.points] == [0.5, 1.0]
    h = handler()
    assert h.set_trajectory(command, now=1.0).accepted
    np.testing.assert_allclose(h.sample(2.75).positions, [2.0, 1.0, INITIAL[2]])
    np.testing.assert_allclose(h.sample(3.25).positions, [4.0, 3.0, INITIAL[2]])


def test_bad_joint_trajectory_message_is_rejected():
    msg = ros_trajectory(('a', 'b', 'c'), [([1.0, 2.0, 3.0], [], 1, 0),
                                           ([1.0, 2.0, 3.0], [], 0, 900_000_000)])
    result = handler().set_trajectory(inbound.trajectory_command(msg), now=0.0)
    assert result.reason is Reason.TIME_NOT_INCREASING


def test_float64_multi_array_message_drives_the_handler():
    layout = F.make('std_msgs/msg/MultiArrayLayout', dim=[], data_offset=0)
    msg = received(F.make('std_msgs/msg/Float64MultiArray', layout=layout,
                          data=F.float64_sequence([0.5, 0.6, 0.7])))
    h = handler()
    assert h.set_positions(inbound.array_command(msg), now=0.0).accepted
    np.testing.assert_array_equal(h.sample(1.0).positions, [0.5, 0.6, 0.7])
