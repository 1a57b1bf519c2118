"""Simulation.reset: the run that follows is a fresh start's (up to the rounding of sim time,
which keeps counting forward), whatever step the reset comes at."""
import numpy as np
import pytest

from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation


@pytest.mark.parametrize('method', ['implicit', 'ema'])
def test_a_reset_between_control_ticks_replays_a_fresh_start(method):
    """The quadruped stands on bent legs and its servos are set every few steps: a reset
    between two ticks must set them at once (not leave mj_resetData's zero targets for the
    rest of the tick), and the sand engine must not carry its memory across."""
    scene = load_scene('quadruped', {'rft.low_velocity.method': method, 'duration': 1.0})
    fresh, reset = Simulation(scene), Simulation(scene)
    control_every = int(round(1.0 / (scene.control_rate * scene.timestep)))
    assert control_every > 1
    reset.step(10 * control_every + 1)  # mid-tick
    reset.reset()
    for _ in range(3):
        fresh.step(1)
        reset.step(1)
        np.testing.assert_allclose(reset.data.ctrl, fresh.data.ctrl, rtol=0, atol=1e-12)
    fresh.step(200)
    reset.step(200)
    assert np.abs(fresh.data.qvel).max() > 1e-3  # a walk, not a robot at rest
    np.testing.assert_allclose(reset.data.qpos, fresh.data.qpos, rtol=0, atol=1e-9)
    np.testing.assert_allclose(reset.data.qvel, fresh.data.qvel, rtol=0, atol=1e-7)
