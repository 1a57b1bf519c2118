"""Joint friction (MJCF frictionloss) solved with the sand by the implicit law: the
regularised Coulomb law, analytic in the air, and a legged body with joint friction standing
in sand settles instead of jittering between the sets; and MuJoCo's other constraint forces
(a joint held at its limit) in the solve."""
import mujoco
import numpy as np
import pytest

from rft_sim_ros.sand.engine import LowVelocity, SandEngine
from rft_sim_ros.sand.geoms import body_plates

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


STANDING = """
<mujoco><option timestep="0.001" integrator="implicitfast"/>
<default><joint damping="0.1" frictionloss="{friction}" armature="0.01"/>
  <position kp="60" kv="1.5"/></default>
<worldbody>
  <body name="torso" pos="0 0 0.24"><freejoint/>
    <geom type="box" size="0.15 0.08 0.03" mass="4"/>
    {legs}
  </body>
</worldbody>
<actuator>{servos}</actuator></mujoco>"""
LEG = """<body name="thigh{i}" pos="{x} {y} 0"><joint name="hip{i}" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.015" mass="0.3"/>
      <body name="shin{i}" pos="0 0 -0.1"><joint name="knee{i}" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.012" mass="0.1"/>
        <geom type="sphere" pos="0 0 -0.1" size="0.02" mass="0.05"/>
      </body></body>"""


def _four_legs(friction=0.0, knee_range=None):
    corners = [(0.12, 0.1), (0.12, -0.1), (-0.12, 0.1), (-0.12, -0.1)]
    legs = ''.join(LEG.format(i=i, x=x, y=y) for i, (x, y) in enumerate(corners))
    if knee_range is not None:
        legs = legs.replace('<joint name="knee', f'<joint range="{knee_range}" '
                            'limited="true" name="knee')
    servos = ''.join(f'<position joint="{j}{i}"/>' for i in range(4) for j in ('hip', 'knee'))
    model = mujoco.MjModel.from_xml_string(STANDING.format(friction=friction, legs=legs,
                                                           servos=servos))
    data = mujoco.MjData(model)
    plates = {f'shin{i}': body_plates(model, model.body(f'shin{i}').id, count=150)
              for i in range(4)}
    return model, data, SandEngine(model, data, plates, zeta=3.75)


@pytest.mark.parametrize('friction', [0.0, 0.2])
def test_a_legged_body_with_joint_friction_comes_to_rest_in_sand(friction):
    """Four servoed legs, each joint with 0.2 N m of friction (as vendor MJCFs have), standing
    in sand: one solve a step and the body at rest, as without friction. (With MuJoCo's own
    friction constraint acting after the sand's solve, such a robot needed about eight
    solves a step, every step unsettled, and jittered at about 1 mm/s.)"""
    model, data, engine = _four_legs(friction)
    assert len(engine.joint_friction) == (8 if friction else 0)
    for _ in range(1500):  # land and settle
        engine.step()
    solves, unsettled = engine.solves, engine.unsettled_steps
    top = 0.0
    for _ in range(1000):
        engine.step()
        top = max(top, np.linalg.norm(data.qvel[:3]))
    assert engine.solves - solves == 1000 and engine.unsettled_steps == unsettled
    assert top < 1e-4  # m/s
    assert data.qpos[2] < 0.24  # standing in the sand, not on anything else


def test_a_body_standing_on_joints_held_at_their_limits_rests_in_sand():
    """The knees' servos push them 0.2 rad past their stops, which hold them: the body stands
    as high as with free knees, and comes to rest. (With the limits' constraint forces left
    out of the sand's solve, the stance jittered at 6 cm/s and sank 4.5 cm deeper.)"""
    heights = []
    for knee_range in (None, '0 1'):
        model, data, engine = _four_legs(knee_range=knee_range)
        if knee_range is not None:
            data.ctrl[1::2] = -0.2
        for _ in range(1500):
            engine.step()
        top = 0.0
        for _ in range(1000):
            engine.step()
            top = max(top, np.linalg.norm(data.qvel[:3]))
        heights.append(data.qpos[2])
        assert top < (1e-4 if knee_range is None else 2e-3)  # m/s
    assert data.nefc == 4  # (the four knees at their stops)
    assert heights[1] == pytest.approx(heights[0], abs=2e-3)
