"""Published leg wrenches are the mean over the publish period (a filtered foot sensor), not an
instantaneous sample that aliases the force ripple at the servo update period."""
import numpy as np
import pytest

from rft_sim_ros.cli import main
from rft_sim_ros.ros.bag import read_messages
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation
from ros_test_support import SERVO_RIG


def test_leg_wrench_is_the_mean_of_the_step_wrenches_since_the_last_state():
    sim = Simulation(load_scene(SERVO_RIG))
    sim.commands.set_positions([0.3, 0.0], now=0.0)  # swing the foot through the sand
    sim.step(40)
    sim.state()                                       # the mean restarts here
    rows = [sim.engine.body_names.index('foot')]
    forces, moments = [], []                          # per step: force, torque about origin
    for _ in range(13):
        sim.step(1)
        wrench = sim.engine.body_wrenches[rows].sum(axis=0)
        com = sim.data.xipos[sim.engine.body_ids[rows[0]]]  # this step's state (mj_step1)
        forces.append(wrench[:3])
        moments.append(wrench[3:] + np.cross(com, wrench[:3]))
    leg = sim.state().legs[0]
    force = np.mean(forces, axis=0)
    assert np.ptp(np.array(forces)[:, 2]) > 1e-3 * abs(force[2])  # it does vary
    assert leg.force == pytest.approx(force, rel=1e-12, abs=1e-12)
    assert leg.torque == pytest.approx(np.mean(moments, axis=0) - np.cross(leg.point, force),
                                       rel=1e-9, abs=1e-12)
    again = sim.state().legs[0]                      # no step since: this step's wrench
    assert again.force == pytest.approx(forces[-1], rel=1e-12, abs=1e-12)


@pytest.mark.parametrize('gait', ['tripod', 'none'])
def test_bag_gait_cycle_mean_of_the_vertical_forces_is_the_weight(tmp_path, gait):
    """Over the last of two 1 s gait cycles (walking, or standing in the same window) the
    sand carries the robot's weight: the bag's time-weighted mean of the summed vertical leg
    forces is the weight within 0.1 % (instantaneous samples were 1-1.6 % above it)."""
    out = tmp_path / 'run'
    assert main(['run', 'hexapod', '--set', 'rft.plates_per_body=120', '--set',
                 'settle_time=0.4', '--set', 'cycles=2', '--set', f'gait={gait}',
                 '--duration', '2.4', '--out', str(out), '--quiet']) == 0
    sim = Simulation(load_scene('hexapod', {'payload': 0.0}))
    weight = -sim.model.opt.gravity[2] * float(np.sum(sim.model.body_mass))
    vertical = {}
    for topic, time_ns, msg in read_messages(out / 'bag'):
        if topic.endswith('/wrench'):
            vertical[time_ns] = vertical.get(time_ns, 0.0) + msg.wrench.force.z
    times = np.array(sorted(vertical))
    force = np.array([vertical[t] for t in times])
    cycle = np.nonzero((times > 1.4e9) & (times <= 2.4e9 + 1))[0]
    durations = times[cycle] - times[cycle - 1]       # each mean covers its own cycle
    assert durations.sum() == 1_000_000_000
    mean = np.sum(force[cycle] * durations) / durations.sum()
    assert mean == pytest.approx(weight, rel=1e-3)
