"""Hybrid joint commands in the simulation (rft_sim_ros.sim.hybrid_drive): the torque of
tau = kp (q* - q) + kd (dq* - dq) + tau_ff, clipped to the effort limit, checked against a
hand computation; the position actuators restored after; a 50 Hz policy-style stream of
JointState commands holds the bundled quadruped standing in sand."""
import mujoco
import numpy as np
import pytest

from rft_sim_ros.control.joint_state_commands import read_joint_state_command
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation


class JointState:
    """What a topic hardware interface sends (the reader is duck-typed; rosbags' messages
    are checked in test_joint_state_commands)."""

    def __init__(self, name, position=(), velocity=(), effort=()):
        self.name, self.position, self.velocity, self.effort = name, position, velocity, effort


@pytest.fixture(scope='module')
def sim():
    return Simulation(load_scene('quadruped', overrides={'params.gait': 'none'}))


def command(sim, **fields):
    index = {name: i for i, name in enumerate(sim.commands.joint_names)}
    return read_joint_state_command(JointState(list(sim.servo_joint_names), **fields), index)


def actuator_parameters(sim):
    m = sim.model
    return [array.copy() for array in (m.actuator_gainprm, m.actuator_biasprm,
                                       m.actuator_ctrllimited, m.actuator_forcelimited,
                                       m.actuator_forcerange)]


def test_the_torque_is_the_law_clipped_to_the_effort_limit(sim):
    sim.reset()
    before = actuator_parameters(sim)
    names = sim.servo_joint_names
    sim.hybrid_drive.set_gains({'*': {'kp': 25.0, 'kd': 0.7}, 'fl_knee': {'kp': 0.0}})
    q0 = sim.data.qpos[sim._command_qpos].copy()
    target = q0 + np.linspace(-0.2, 0.2, len(names))
    velocity = np.linspace(1.0, -1.0, len(names))
    effort = np.full(len(names), 1.5)
    effort[names.index('fr_knee')] = 500.0     # far beyond its 30 N m
    effort[names.index('rl_hip_pitch')] = -500.0  # beyond -20 N m
    sim.commands.set_joint_states(command(sim, position=target, velocity=velocity,
                                          effort=effort), sim.time)
    sim.step(3)
    mujoco.mj_forward(sim.model, sim.data)
    q = sim.data.qpos[sim._command_qpos]
    dq = sim.data.qvel[sim.model.jnt_dofadr[[sim.model.joint(n).id for n in names]]]
    kp = np.full(len(names), 25.0)
    kp[names.index('fl_knee')] = 0.0
    limit = np.array([30.0 if n.endswith('knee') else 20.0 for n in names])  # the URDF's
    by_hand = np.clip(kp * (target - q) + 0.7 * (velocity - dq) + effort, -limit, limit)
    assert by_hand[names.index('fr_knee')] == 30.0
    assert by_hand[names.index('rl_hip_pitch')] == -20.0
    forces = sim.data.actuator_force
    np.testing.assert_allclose(forces[sim.interfaces.position_actuators], by_hand,
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(forces[sim.interfaces.effort_actuators], 0.0)
    assert sim.interfaces.mode == 'hybrid'
    sim.commands.set_positions(q0, sim.time)
    sim.step(sim._control_every)  # (one control tick)
    for restored, original in zip(actuator_parameters(sim), before):
        np.testing.assert_array_equal(restored, original)
    sim.hybrid_drive.set_gains({})


def test_a_50_hz_policy_stream_holds_the_quadruped_standing(sim):
    sim.reset()
    sim.hybrid_drive.set_gains({'*': {'kp': 40.0, 'kd': 1.0}})  # a policy's gains
    base = sim.model.body('base').id
    height0 = sim.data.xpos[base, 2]
    stand = sim.data.qpos[sim._command_qpos].copy()
    zero = np.zeros(len(stand))
    every = int(round(0.02 / sim.timestep))
    for _ in range(100):  # 2 s of 50 Hz commands
        sim.commands.set_joint_states(command(sim, position=stand, velocity=zero, effort=zero),
                                      sim.time)
        sim.step(every)
    assert sim.interfaces.mode == 'hybrid'
    up = sim.data.xmat[base].reshape(3, 3)[:, 2]
    tilt = np.degrees(np.arccos(up[2]))
    sag = height0 - sim.data.xpos[base, 2]
    assert tilt < 3.0 and -0.005 < sag < 0.03, (tilt, sag)  # standing, not sinking or fallen
    joints = sim.data.qpos[sim._command_qpos]
    assert np.max(np.abs(joints - stand)) < 0.15  # the soft gains' sag under the weight
    assert np.linalg.norm(sim.data.qvel[:6]) < 0.05  # at rest
    sim.hybrid_drive.set_gains({})


def test_a_position_target_beyond_the_joints_range_is_held_at_its_end(sim):
    """q* beyond a joint's range (the URDF's limits): the law pulls to the end of the range
    (as the position servos' targets are held within it), not into MuJoCo's soft limit."""
    sim.reset()
    names = sim.servo_joint_names
    knee = names.index('fl_knee')
    low, high = sim.model.jnt_range[sim.model.joint('fl_knee').id]
    target = sim.data.qpos[sim._command_qpos].copy()
    target[knee] = low - 2.0
    sim.commands.set_joint_states(command(sim, position=target), sim.time)
    sim.step(2)
    controls = sim.data.ctrl[sim.interfaces.position_actuators]
    assert controls[knee] == pytest.approx(sim.hybrid_drive.kp[knee] * low)
    sim.step(1000)
    assert sim.data.joint('fl_knee').qpos[0] == pytest.approx(low, abs=0.05)


def test_joints_declaring_only_efforts_are_pure_effort_and_only_velocities_turn(sim):
    """A joint whose <ros2_control> block declares an effort command interface alone: tau =
    tau_ff, no kp or kd; one declaring a velocity interface and no position one: its target
    moves at its velocity, so the joint turns at it (kp does not hold it)."""
    sim.reset()
    names = list(sim.servo_joint_names)
    declared = {name: ('position', 'velocity', 'effort') for name in names}
    declared['fl_knee'], declared['fr_hip_pitch'] = ('effort',), ('velocity',)
    nan = np.full(len(names), np.nan)
    effort, velocity = nan.copy(), nan.copy()
    effort[names.index('fl_knee')] = 2.5
    velocity[names.index('fr_hip_pitch')] = 0.5
    index = {name: i for i, name in enumerate(sim.commands.joint_names)}
    sim.commands.set_joint_states(read_joint_state_command(
        JointState(names, position=nan, velocity=velocity, effort=effort), index, declared),
        sim.time)
    sim.step(2)
    assert sim.data.actuator(sim.interfaces.position_actuators[
        names.index('fl_knee')]).force[0] == pytest.approx(2.5)  # (tau_ff alone)
    hip = sim.data.joint('fr_hip_pitch')
    start, time = hip.qpos[0], sim.time
    sim.step(200)
    assert (hip.qpos[0] - start) / (sim.time - time) == pytest.approx(0.5, rel=0.1)


def test_a_velocity_only_joint_that_cannot_follow_does_not_wind_its_target_up(sim):
    """A joint declaring a velocity interface alone, commanded far faster than its effort
    limit lets it turn: its q* stays within the lag whose kp term reaches that limit (it
    pushes at its limit), not running away from the joint."""
    sim.reset()
    names = list(sim.servo_joint_names)
    declared = {name: ('position', 'velocity', 'effort') for name in names}
    declared['fr_hip_pitch'] = ('velocity',)
    velocity = np.full(len(names), np.nan)
    velocity[names.index('fr_hip_pitch')] = 200.0
    index = {name: i for i, name in enumerate(sim.commands.joint_names)}
    sim.commands.set_joint_states(read_joint_state_command(
        JointState(names, velocity=velocity), index, declared), sim.time)
    sim.step(8)
    i = names.index('fr_hip_pitch')
    lag = sim.commands.hybrid.positions[i] - sim.data.joint('fr_hip_pitch').qpos[0]
    limit, kp = sim.interfaces.gains['fr_hip_pitch'].effort, sim.hybrid_drive.kp[i]
    assert 0.0 < lag <= limit / kp * 1.05  # (the joint moved a step since the last tick)
    assert 200.0 * 0.008 > 5 * limit / kp  # (unclamped, it would be far ahead)
