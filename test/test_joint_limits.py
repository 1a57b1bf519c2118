"""sim/joint_limits.py: a joint pushed past its range by more than a soft limit yields is
recorded (the farthest, with its side of the range and when) and said in the run's words;
one within its range, or just into its stop, is not."""
import math

import mujoco
import pytest

from rft_sim_ros.sim.joint_limits import OVERRUN_M, OVERRUN_RAD, LimitWatch, words

RIG = """<mujoco><compiler angle="radian"/><worldbody><body>
  <joint name="hip" axis="0 1 0" range="-1.5 1.5"/>
  <joint name="free_spin" axis="1 0 0"/>
  <joint name="slide" type="slide" axis="0 0 1" range="0 0.1"/>
  <geom size="0.1" mass="1"/></body></worldbody></mujoco>"""


def _at(model, data, hip, slide):
    data.joint('hip').qpos[0], data.joint('slide').qpos[0] = hip, slide
    data.joint('free_spin').qpos[0] = 100.0  # (not limited: never counted)


def test_the_joint_farthest_past_its_range_is_recorded_and_said():
    model = mujoco.MjModel.from_xml_string(RIG)
    data = mujoco.MjData(model)
    watch = LimitWatch(model)
    _at(model, data, 1.5 + 0.5 * OVERRUN_RAD, 0.1 + 0.5 * OVERRUN_M)  # into the stops only
    watch.observe(data, 0.1)
    assert watch.result() is None
    _at(model, data, -1.5 - 2 * OVERRUN_RAD, 0.1 + 3 * OVERRUN_M)
    watch.observe(data, 0.2)
    assert watch.result() == {'joint': 'slide', 'past_limit_m': pytest.approx(3 * OVERRUN_M),
                              'limit_m': 0.1, 'time_s': 0.2}
    _at(model, data, 2.93, 0.05)  # (the trial's hip: 82 deg past its 1.5 rad stop)
    watch.observe(data, 0.3)
    _at(model, data, 1.6, 0.05)  # (back: the farthest look is kept)
    watch.observe(data, 0.4)
    past = watch.result()
    assert past['joint'] == 'hip' and past['limit_rad'] == 1.5 and past['time_s'] == 0.3
    assert math.degrees(past['past_limit_rad']) == pytest.approx(81.9, abs=0.1)
    assert words(past).startswith('joint hip went 82 deg past its limit (1.5 rad) at t = '
                                  "0.30 s: MuJoCo's joint limits are soft")
    watch.start()
    assert watch.result() is None


def test_a_command_beyond_the_range_holds_at_the_stop_and_a_push_through_it_is_said(
        tmp_path):
    """A hinge commanded to twice its range: its servo's target is held within the range
    (the servo's control range), so it stops there; an effort far beyond what MuJoCo's soft
    limit holds pushes it through, and the outcome names the joint."""
    from rft_sim_ros.scenes.config import load_scene
    from rft_sim_ros.sim.simulation import Simulation
    arm = tmp_path / 'arm.xml'
    arm.write_text("""<mujoco><compiler angle="radian"/><worldbody>
      <body name="post" pos="0 0 0.5"><geom type="box" size="0.02 0.02 0.02" mass="1"/>
      <body name="link"><joint name="swing" axis="0 1 0" range="-0.5 0.5"/>
      <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.01" mass="0.2"/></body></body>
      </worldbody></mujoco>""")
    scene = load_scene(arm, {'sand.surface_height': -1.0, 'rft.sand_bodies': ['link'],
                             'rft.plates_per_body': 50})
    held = Simulation(scene)
    held.commands.set_positions([1.0], held.time)
    held.step(500)
    assert held.data.joint('swing').qpos[0] == pytest.approx(0.5, abs=OVERRUN_RAD)
    assert held.outcome()['joint_past_limit'] is None
    pushed = Simulation(scene)
    pushed.commands.set_efforts([50.0], pushed.time)
    pushed.step(500)
    outcome = pushed.outcome()
    assert outcome['joint_past_limit']['joint'] == 'swing'
    assert outcome['joint_past_limit']['limit_rad'] == 0.5
    assert outcome['joint_past_limit']['past_limit_rad'] > OVERRUN_RAD
    assert 'joint swing went' in outcome['words']
