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


@pytest.mark.parametrize('scene', ['plate_drop', 'plate_press'])
def test_a_scenarios_metrics_after_a_reset_are_a_fresh_starts(scene):
    """What a scenario records for its metrics starts afresh at a reset (a run at another
    zeta before it leaves nothing behind)."""
    fresh, reset = Simulation(load_scene(scene)), Simulation(load_scene(scene))
    fresh.step(600)
    reset.zeta = 1.0
    reset.step(300)
    reset.zeta = 3.75
    reset.reset()
    reset.step(600)
    assert reset.scenario.metrics(reset) == fresh.scenario.metrics(fresh)


def test_the_leg_wrenches_after_a_reset_are_a_fresh_starts():
    """The legs' mean wrenches (what a state reports) sum the steps since they were last
    read: a reset starts that sum afresh, so an episode's steps left unread before the reset
    do not show in the next one's first state."""
    fresh, reset = Simulation(load_scene('hexapod')), Simulation(load_scene('hexapod'))
    reset.step(1500)  # standing and walking in the sand, its wrenches never read
    reset.reset()
    for sim in (fresh, reset):
        sim.step(20)  # falling towards the sand: no leg touches it yet
    np.testing.assert_array_equal(reset.data.qpos, fresh.data.qpos)
    forces = [np.array([leg.force for leg in sim.leg_wrenches()]) for sim in (fresh, reset)]
    assert not np.any(forces[0])
    np.testing.assert_array_equal(forces[1], forces[0])


STILT = """<mujoco><worldbody>
  <body name="trunk" pos="0 0 1"><freejoint/>
    <geom type="box" size="0.1 0.1 0.1" pos="0.05 0 0" mass="5"/>
    <body name="stilt" pos="0 0 -0.1"><joint name="hip" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.8" size="0.01" mass="0.1"/>
      <body name="foot" pos="0 0 -0.82"><geom type="sphere" size="0.02" mass="0.05"/></body>
    </body>
  </body></worldbody></mujoco>"""


def test_a_robot_that_falls_while_settling_starts_as_drop_0_would_have_started_it(tmp_path):
    """A trunk on one stilt topples while spawn rest settles it and comes to rest on the
    sand, its base turned more than 45 deg: it counts as fallen, and it starts from the state
    before the settling instead, exactly as spawn drop:0 starts it; start-up says what it saw
    and did once, resets included."""
    path = tmp_path / 'stilt.xml'
    path.write_text(STILT)
    sim = Simulation(load_scene(path, {'rft.plates_per_body': 50}))
    dropped = Simulation(load_scene(path, {'rft.plates_per_body': 50, 'robot.spawn': 'drop:0'}))
    assert sim.settle_steps > 1000 and dropped.settle_steps == 0
    assert not [n for n in dropped.notices if 'spawn rest' in n]
    np.testing.assert_array_equal(sim.data.qpos, dropped.data.qpos)
    assert not sim.data.qvel.any() and sim.data.time == 0.0
    sim.step(100)
    dropped.step(100)
    np.testing.assert_allclose(sim.data.qpos, dropped.data.qpos, rtol=0, atol=1e-12)
    sim.reset()
    [notice] = [n for n in sim.notices if 'spawn rest' in n]
    assert notice.startswith('spawn rest: fell: its base (trunk) came to rest turned ')
    assert 'deg from how it was set down (up to ' in notice and 'on its side or back' in notice
    assert 'it starts as spawn drop:0 starts it instead' in notice


def test_a_robot_still_moving_when_settling_ends_starts_as_drop_0_would(tmp_path, monkeypatch):
    """Settling gives up after SETTLE_LIMIT_S (here cut to 50 ms, while the stilt is still
    toppling, its trunk far above the sand): the robot starts as drop:0 starts it."""
    from rft_sim_ros.sim import simulation
    monkeypatch.setattr(simulation, 'SETTLE_LIMIT_S', 0.05)
    path = tmp_path / 'stilt.xml'
    path.write_text(STILT)
    sim = Simulation(load_scene(path, {'rft.plates_per_body': 50}))
    dropped = Simulation(load_scene(path, {'rft.plates_per_body': 50, 'robot.spawn': 'drop:0'}))
    assert sim.settle_steps == round(0.05 / sim.timestep)
    np.testing.assert_array_equal(sim.data.qpos, dropped.data.qpos)
    [notice] = [n for n in sim.notices if 'spawn rest' in n]
    assert notice.startswith('spawn rest: still moving after 0.05 s: its base (trunk) at ')
    assert 'as a robot that cannot stand' not in notice  # (it said so of robots that stood)
    # the same robot touching rigid ground (a world box at the sand's surface) is told so
    path.write_text(STILT.replace('<worldbody>', '<worldbody><geom name="slab" type="box" '
                                  'size="2 2 0.05" pos="0 0 -0.05"/>'))
    [notice] = [n for n in Simulation(load_scene(path, {'rft.plates_per_body': 50})).notices
                if 'spawn rest' in n]
    assert notice.startswith('spawn rest: still moving after 0.05 s: its base (trunk) at ')
    assert 'touching rigid geoms (' in notice and 'on which it may slide' in notice


def test_a_robot_on_a_slope_is_set_down_turned_to_it_and_stands(tmp_path):
    """spawn rest on a slope turns the robot to the slope's plane under its sand bodies
    before it is set down (said at start-up), so that its feet meet the sand together: a
    four-legged table (plates on its feet only) settles on a 15 deg slope, its top within
    2 deg of the slope's plane (the downhill feet carry more and sink more), and stands
    there; on level sand nothing is turned."""
    path = tmp_path / 'table.xml'
    path.write_text(TABLE)
    for downhill in (90.0, 200.0):
        sim = Simulation(load_scene(path, {
            'rft.plates_per_body': 50, 'sand.surface.type': 'slope',
            'sand.surface.angle_deg': 15.0, 'sand.surface.downhill_deg': downhill}))
        up = sim.data.xmat[sim.model.body('top').id].reshape(3, 3)[:, 2]
        normal = np.asarray(sim.engine.surface.normal(0.0, 0.0)).reshape(3)
        assert np.degrees(np.arccos(up @ normal)) < 2.0
        [notice] = [n for n in sim.notices if 'turned' in n]
        assert notice.startswith('robot.spawn rest: turned 15 deg to the sand surface')
        assert not [n for n in sim.notices if n.startswith('spawn rest:')]  # it settled
        start = sim.data.qpos[:3].copy()
        sim.step(int(0.5 / sim.timestep))
        assert np.linalg.norm(sim.data.qpos[:3] - start) < 1e-3
    level = Simulation(load_scene(path, {'rft.plates_per_body': 50}))
    assert not [n for n in level.notices if 'turned' in n]
    np.testing.assert_allclose(level.data.xmat[level.model.body('top').id].reshape(3, 3)[:, 2],
                               [0.0, 0.0, 1.0], atol=1e-6)


TABLE = """<mujoco><worldbody>
  <body name="top" pos="0 0 1"><freejoint/>
    <geom type="box" size="0.3 0.15 0.02" mass="4"/>
""" + ''.join(f"""    <body name="leg{i}" pos="{x} {y} -0.02"><joint name="hip{i}" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.01" mass="0.1"/>
      <body name="foot{i}" pos="0 0 -0.22"><geom type="box" size="0.03 0.03 0.01" mass="0.05"/>
      </body></body>
""" for i, (x, y) in enumerate([(0.25, 0.1), (0.25, -0.1), (-0.25, 0.1), (-0.25, -0.1)])) + """
  </body></worldbody></mujoco>"""
