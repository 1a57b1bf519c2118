"""Gait trajectories for the tripod_gait publisher: what it sends, and that a
joint_trajectory_controller-style receiver (CommandHandler) reproduces the gait from them."""
import itertools

import numpy as np
import pytest

from rft_sim_ros.ros import inbound, messages
from rft_sim_ros.ros.factory import RosbagsFactory
from rft_sim_ros.ros.gait_trajectory import GaitTrajectories
from rft_sim_ros.control.commands import CommandHandler, TrajectoryCommand, TrajectoryPoint
from rft_sim_ros.scenes.gaits import make_gait
from rft_sim_ros.scenes.hexapod import JOINT_NAMES

FACTORY = RosbagsFactory()


def tripod(start):
    return make_gait('tripod', start_time_s=start, ramp_time_s=0.5)


def test_nothing_is_sent_before_sim_time_starts():
    trajectories = GaitTrajectories(tripod)
    assert trajectories.command(0.0) is None and trajectories.gait is None


def test_a_command_samples_the_gait_over_the_horizon():
    trajectories = GaitTrajectories(tripod, horizon_s=0.25, spacing_s=0.05, start_delay_s=1.0)
    now = 2.0
    command = trajectories.command(now)
    gait = trajectories.gait
    assert gait.start_time_s == 3.0                # first sim time seen + start delay
    assert command.start_time == now and tuple(command.joint_names) == JOINT_NAMES
    assert [p.time_from_start for p in command.points] == pytest.approx(
        [0.0, 0.05, 0.1, 0.15, 0.2, 0.25])
    later = trajectories.command(3.7)
    assert trajectories.gait is gait               # the gait's clock is fixed once
    for point in later.points:
        t = 3.7 + point.time_from_start
        np.testing.assert_allclose(point.positions, gait.targets(t), atol=1e-12)
        h = 1e-6
        np.testing.assert_allclose(point.velocities,
                                   (gait.targets(t + h) - gait.targets(t - h)) / (2 * h),
                                   atol=1e-4)
    assert np.any(np.abs(later.points[0].velocities) > 0.1)  # walking, not standing


@pytest.mark.parametrize('options', [dict(horizon_s=0.0), dict(spacing_s=-0.1),
                                     dict(spacing_s=0.5, horizon_s=0.25),
                                     dict(start_delay_s=float('nan'))])
def test_bad_settings_are_refused(options):
    with pytest.raises(ValueError):
        GaitTrajectories(tripod, **options)


def test_joint_trajectory_message_round_trips():
    command = TrajectoryCommand(
        joint_names=('a', 'b'), start_time=12.5,
        points=(TrajectoryPoint([1.0, 2.0], 0.0, [0.1, -0.2]), TrajectoryPoint([1.5, 2.5], 0.25)))
    msg = messages.joint_trajectory_message(FACTORY, command)
    ts = FACTORY.typestore
    back = inbound.trajectory_command(ts.deserialize_cdr(ts.serialize_cdr(msg, msg.__msgtype__),
                                                         msg.__msgtype__))
    assert back.start_time == 12.5 and back.joint_names == ('a', 'b')
    assert [p.time_from_start for p in back.points] == [0.0, 0.25]
    np.testing.assert_array_equal(back.points[0].velocities, [0.1, -0.2])
    assert len(back.points[1].velocities) == 0
    assert list(msg.points[0].accelerations) == [] and list(msg.points[0].effort) == []


def test_a_receiver_fed_at_the_publish_rate_follows_the_gait():
    """Published at 20 Hz (horizon 0.25 s, waypoints 20 ms apart) and delivered 7 ms late,
    the interpolated targets stay within 2 mrad of the gait at a 500 Hz servo rate."""
    trajectories = GaitTrajectories(tripod, horizon_s=0.25, spacing_s=0.02, start_delay_s=0.5)
    handler = CommandHandler(JOINT_NAMES, np.zeros(len(JOINT_NAMES)))
    latency, publish_period = 0.007, 0.05
    sent = [(k * publish_period + latency, trajectories.command(k * publish_period))
            for k in range(1, 80)]
    worst = 0.0
    for t in np.arange(0.3, 3.5, 0.002):
        while sent and sent[0][0] <= t:
            delivered, command = sent.pop(0)
            msg = messages.joint_trajectory_message(FACTORY, command)
            assert handler.set_trajectory(inbound.trajectory_command(msg), now=delivered).accepted
        worst = max(worst, np.max(np.abs(handler.sample(t).positions
                                         - trajectories.gait.targets(t))))
    assert worst < 2e-3


def test_the_hexapod_walks_on_gait_trajectories_sent_through_the_node_core():
    """What walk.launch.py does, without ROS: tripod_gait's trajectories (as JointTrajectory
    messages, every 0.05 s of sim time) into SimRuntime driving the hexapod scene with its
    built-in gait off."""
    from rft_sim_ros.ros.runtime import SimRuntime
    from rft_sim_ros.sim.runner import run_scene
    from rft_sim_ros.scenes.config import load_scene
    from rft_sim_ros.sim.simulation import Simulation
    from ros_test_support import ListSink

    sim = Simulation(load_scene('hexapod', {'gait': 'none', 'rft.plates_per_body': 150}))
    sink = ListSink()
    wall = itertools.count(0.0, 0.06)   # each clock reading 60 ms on: one cycle per tick
    runtime = SimRuntime(sim, sink, publish_rate=100.0, real_time_factor=0.0,
                         clock=lambda: next(wall), tick_budget_s=0.05)
    trajectories = GaitTrajectories(lambda start: make_gait('tripod', start_time_s=start),
                                    start_delay_s=1.0)
    next_send = 0.0
    while sim.time < 3.0:
        runtime.tick()
        if sim.time >= next_send:
            command = trajectories.command(sim.time)
            if command is not None:
                msg = messages.joint_trajectory_message(FACTORY, command)
                assert runtime.on_trajectory(msg).accepted
            next_send += 0.05
    y = {round(s.time, 2): s.base_position[1] for s in sink.states}  # it walks along +y
    standing = [value for t, value in y.items() if t <= 1.0]
    assert max(abs(v) for v in standing) < 0.005          # no gait yet: it stands
    # the same walk as the scene's built-in gait (which starts at 1.0 s, not 1.01 s)
    built_in = run_scene(load_scene('hexapod', {'rft.plates_per_body': 150, 'cycles': 2}),
                         progress=False, plots=False)['metrics']['forward_distance_m']
    assert built_in > 0.1
    assert sink.states[-1].base_position[1] == pytest.approx(built_in, rel=0.05)
    assert runtime.rejections == {} and not runtime.diverged
