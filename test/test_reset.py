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


STILT = """<mujoco><worldbody>
  <body name="trunk" pos="0 0 1"><freejoint/>
    <geom type="box" size="0.1 0.1 0.1" pos="0.05 0 0" mass="5"/>
    <body name="stilt" pos="0 0 -0.1"><joint name="hip" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.8" size="0.01" mass="0.1"/>
      <body name="foot" pos="0 0 -0.82"><geom type="sphere" size="0.02" mass="0.05"/></body>
    </body>
  </body></worldbody></mujoco>"""


def test_a_robot_that_cannot_stand_starts_as_drop_0_would_have_started_it(tmp_path):
    """A trunk on one stilt topples while spawn rest settles it (only its foot is in the
    sand, so the trunk would start fallen into it): it starts from the state before the
    settling instead, exactly as spawn drop:0 starts it, and start-up says so once, resets
    included."""
    path = tmp_path / 'stilt.xml'
    path.write_text(STILT)
    sim = Simulation(load_scene(path, {'rft.plates_per_body': 50}))
    dropped = Simulation(load_scene(path, {'rft.plates_per_body': 50, 'robot.spawn': 'drop:0'}))
    assert sim.settle_steps > 1000 and dropped.settle_steps == 0
    assert not [n for n in dropped.notices if 'still moving' in n]
    np.testing.assert_array_equal(sim.data.qpos, dropped.data.qpos)
    assert not sim.data.qvel.any() and sim.data.time == 0.0
    sim.step(100)
    dropped.step(100)
    np.testing.assert_allclose(sim.data.qpos, dropped.data.qpos, rtol=0, atol=1e-12)
    sim.reset()
    [notice] = [n for n in sim.notices if 'still moving' in n]
    assert 'it starts as spawn drop:0 starts it instead' in notice
