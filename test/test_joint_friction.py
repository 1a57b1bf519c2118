"""Joint friction (MJCF frictionloss) solved with the sand by the implicit law: the
regularised Coulomb law, analytic in the air, and a legged body with joint friction standing
in sand settles instead of jittering between the sets."""
import mujoco
import numpy as np
import pytest

from rft_sim_ros.sand.engine import LowVelocity, SandEngine
from rft_sim_ros.sand.geoms import body_plates
from standing_body import four_legs, settle

SLIDER = """
<mujoco><option timestep="0.001" gravity="0 0 0"/>
<worldbody>
  <body name="cart" pos="0 0 1"><joint name="rail" type="slide" axis="1 0 0"
                                        frictionloss="{friction}"/>
    <geom type="box" size="0.05 0.05 0.05" mass="2"/>
  </body>
</worldbody></mujoco>"""


def _slider(friction=3.0, method='implicit'):
    model = mujoco.MjModel.from_xml_string(SLIDER.format(friction=friction))
    data = mujoco.MjData(model)
    plates = {'cart': body_plates(model, 1, count=50)}  # (1 m above the sand)
    engine = SandEngine(model, data, plates, zeta=1.0, low_velocity=LowVelocity(method))
    return model, data, engine


@pytest.mark.parametrize('push', [5.0, -5.0, 2.0, -2.9])
def test_coulomb_friction_of_a_slide_joint_pushed_from_rest(push):
    """A 2 kg cart on a rail with 3 N of friction, pushed by a constant force from rest: above
    the friction it accelerates at (|P| - F) / m from the first step (no breakaway lag),
    below it stays stuck, creeping at most at rest_speed x P / F."""
    model, data, engine = _slider()
    assert engine.joint_friction == {0: 3.0} and model.dof_frictionloss[0] == 0.0
    data.qfrc_applied[0] = push
    for _ in range(500):
        engine.step()
    speed = data.qvel[0]
    if abs(push) > 3.0:
        assert speed == pytest.approx(np.sign(push) * (abs(push) - 3.0) / 2.0 * data.time,
                                      rel=1e-9)
    else:
        assert abs(speed) <= LowVelocity().rest_speed * abs(push) / 3.0 * (1 + 1e-9)
        assert engine.solves == 500 and engine.unsettled_steps == 0


def test_friction_stops_a_sliding_joint_and_holds_it():
    """Sliding at 0.3 m/s with no push, the cart decelerates at F / m and stops at
    v0^2 m / (2 F) (to the distance one step covers), and then stays at rest."""
    model, data, engine = _slider()
    data.qvel[0] = 0.3
    for _ in range(300):
        engine.step()
    assert data.qpos[0] == pytest.approx(0.3 ** 2 * 2.0 / (2 * 3.0), abs=0.3 * 0.001)
    assert abs(data.qvel[0]) < 1e-9


def test_explicit_methods_leave_joint_friction_to_mujoco():
    model, data, engine = _slider(method='none')
    assert engine.joint_friction == {} and model.dof_frictionloss[0] == 3.0


@pytest.mark.parametrize('friction', [0.0, 0.2])
def test_a_legged_body_with_joint_friction_comes_to_rest_in_sand(friction):
    """Four servoed legs, each joint with 0.2 N m of friction (as vendor MJCFs have), standing
    in sand: one solve a step and the body at rest, as without friction. (With MuJoCo's own
    friction constraint acting after the sand's solve, such a robot needed about eight
    solves a step, every step unsettled, and jittered at about 1 mm/s.)"""
    model, data, engine = four_legs(friction)
    assert len(engine.joint_friction) == (8 if friction else 0)
    solves, unsettled, top = settle(data, engine)
    assert solves == 1000 and unsettled == 0
    assert top < 1e-4  # m/s
    assert data.qpos[2] < 0.24  # standing in the sand, not on anything else
