"""Equality constraints (MJCF <equality>: connect, weld, joint, tendon) solved with the sand
by the implicit law, as the rows MuJoCo makes for them: in the air the motion is MuJoCo's
own, with a dense or a sparse constraint Jacobian, and a robot whose leg joints a stiff
tendon equality couples stands in sand in one solve a step."""
import mujoco
import numpy as np
import pytest

from rft_sim_ros.sand.engine import LowVelocity, SandEngine
from rft_sim_ros.sand.geoms import body_plates

LINKAGE = """
<mujoco><option timestep="0.002"/>
<default><geom contype="0" conaffinity="0"/></default>
<worldbody>
  <body name="upper" pos="0 0 1"><joint name="shoulder" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="0.5"/>
    <body name="fore" pos="0.3 0 0"><joint name="elbow" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="0.3"/>
      <body name="hand" pos="0.3 0 0"><joint name="wrist" axis="0 1 0"/>
        <geom type="sphere" size="0.03" mass="0.2"/></body>
    </body>
  </body>
  <body name="strut" pos="0.6 0 1.3"><joint name="pivot" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.02" mass="0.4"/>
  </body>
  <body name="lever" pos="-0.3 0 1"><joint name="spin" axis="0 1 0"/>
    <joint name="lift" type="slide" axis="0 0 1"/>
    <geom type="box" size="0.05 0.02 0.02" mass="0.3"/>
  </body>
</worldbody>
<tendon><fixed name="pair"><joint joint="shoulder" coef="1"/><joint joint="elbow" coef="0.5"/>
</fixed></tendon>
<equality>
  <tendon tendon1="pair" polycoef="0.1 0 0 0 0"/>
  <joint joint1="wrist" joint2="elbow" polycoef="0 -1 0 0 0"/>
  <connect body1="strut" body2="fore" anchor="0 0 -0.3"/>
  <weld body1="lever"/>
</equality></mujoco>"""


@pytest.mark.parametrize('jacobian', [mujoco.mjtJacobian.mjJAC_DENSE,
                                      mujoco.mjtJacobian.mjJAC_SPARSE])
def test_equalities_in_the_air_move_as_mujocos_own(jacobian):
    """No sand: an arm whose joints a tendon and a joint equality couple, closed into a loop
    by a connect to a pendulum in another branch (rows that are not tree-sparse), and a
    welded body, all started off their constraints and moving: with the equality rows solved
    by the engine (and emptied for MuJoCo's own solve) the motion is MuJoCo's."""
    own = mujoco.MjModel.from_xml_string(LINKAGE)
    model = mujoco.MjModel.from_xml_string(LINKAGE)
    own.opt.jacobian = model.opt.jacobian = jacobian
    own_data, data = mujoco.MjData(own), mujoco.MjData(model)
    engine = SandEngine(model, data, {'hand': body_plates(model, 3, count=50)}, zeta=1.0)
    for d in (own_data, data):
        d.qvel[:] = [1.0, -2.0, 0.5, 0.3, 0.8, 0.1]
    for _ in range(500):
        mujoco.mj_step(own, own_data)
        engine.step()
        assert data.qpos == pytest.approx(own_data.qpos, abs=1e-9)
    assert data.ne == own_data.ne == 11  # tendon 1, joint 1, connect 3, weld 6
    assert np.abs(own_data.efc_force[:11]).max() > 1.0  # (they push)
    assert not data.efc_force[:11].any()  # (the engine's, not MuJoCo's)
    assert engine.solves == 500


STANDING = """
<mujoco><option timestep="0.001" integrator="implicitfast"/>
<default><joint damping="0.1" armature="0.01"/><position kp="60" kv="1.5"/></default>
<worldbody>
  <body name="torso" pos="0 0 0.24"><freejoint/>
    <geom type="box" size="0.15 0.08 0.03" mass="4"/>
    {legs}
  </body>
</worldbody>
<tendon>{tendons}</tendon>
<equality>{equalities}</equality>
<actuator>{servos}</actuator></mujoco>"""
LEG = """<body name="thigh{i}" pos="{x} {y} 0"><joint name="hip{i}" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.015" mass="0.3"/>
      <body name="shin{i}" pos="0 0 -0.1"><joint name="knee{i}" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.012" mass="0.1"/>
        <geom type="sphere" pos="0 0 -0.1" size="0.02" mass="0.05"/>
      </body></body>"""


def test_legs_coupled_by_a_stiff_tendon_equality_stand_in_sand_in_one_solve_a_step():
    """Four legs whose knee follows the hip through a stiff tendon equality (solref 5 ms, as
    dm_control's quadruped couples its leg joints), the hips servoed, standing in sand: one
    solve a step, no step unsettled, the body at rest. (Left to MuJoCo's solve after the
    sand's, the coupling's force undid the end velocities the sand's solve chose: 2.6 solves
    a step, 43 % of the steps unsettled.)"""
    corners = [(0.12, 0.1), (0.12, -0.1), (-0.12, 0.1), (-0.12, -0.1)]
    xml = STANDING.format(
        legs=''.join(LEG.format(i=i, x=x, y=y) for i, (x, y) in enumerate(corners)),
        tendons=''.join(f'<fixed name="couple{i}"><joint joint="hip{i}" coef="1"/>'
                        f'<joint joint="knee{i}" coef="0.5"/></fixed>' for i in range(4)),
        equalities=''.join(f'<tendon tendon1="couple{i}" solref="0.005 0.5"/>'
                           for i in range(4)),
        servos=''.join(f'<position joint="hip{i}"/>' for i in range(4)))
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    plates = {f'shin{i}': body_plates(model, model.body(f'shin{i}').id, count=150)
              for i in range(4)}
    engine = SandEngine(model, data, plates, zeta=3.75)
    for _ in range(1500):  # land and settle
        engine.step()
    solves, unsettled, top = engine.solves, engine.unsettled_steps, 0.0
    for _ in range(1000):
        engine.step()
        top = max(top, np.linalg.norm(data.qvel[:3]))
    assert engine.solves - solves == 1000 and engine.unsettled_steps == unsettled
    assert top < 1e-4  # m/s
    assert data.ne == 4 and data.qpos[2] < 0.24  # coupled, and standing in the sand
    couplings = data.qpos[[7, 9, 11, 13]] + 0.5 * data.qpos[[8, 10, 12, 14]]
    assert np.abs(couplings).max() < 1e-3  # rad: the equality holds


def test_explicit_methods_leave_equalities_to_mujoco():
    """With `ema` or `none` the engine solves nothing but the sand: MuJoCo's rows push."""
    model = mujoco.MjModel.from_xml_string(LINKAGE)
    data = mujoco.MjData(model)
    engine = SandEngine(model, data, {'hand': body_plates(model, 3, count=50)}, zeta=1.0,
                        low_velocity=LowVelocity('none'))
    engine.step()
    assert np.abs(data.efc_force[:data.ne]).max() > 1.0
