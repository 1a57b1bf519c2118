"""Joint friction (MJCF frictionloss) solved with the sand by the implicit law: the
regularised Coulomb law, analytic in the air, and a legged body with joint friction standing
in sand settles instead of jittering between the sets; and MuJoCo's other constraint forces
(a joint held at its limit) in the solve."""
import mujoco
import numpy as np
import pytest

from rft_sim_ros.sand import coupling
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


def _four_legs(friction=0.0, knee_range=None, override=False):
    corners = [(0.12, 0.1), (0.12, -0.1), (-0.12, 0.1), (-0.12, -0.1)]
    legs = ''.join(LEG.format(i=i, x=x, y=y) for i, (x, y) in enumerate(corners))
    if knee_range is not None:
        legs = legs.replace('<joint name="knee', f'<joint range="{knee_range}" '
                            'limited="true" name="knee')
    servos = ''.join(f'<position joint="{j}{i}"/>' for i in range(4) for j in ('hip', 'knee'))
    model = mujoco.MjModel.from_xml_string(STANDING.format(friction=friction, legs=legs,
                                                           servos=servos))
    if override:  # (MuJoCo's solref/solimp override: the engine leaves the limits alone)
        model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_OVERRIDE
        model.opt.o_solref, model.opt.o_solimp = model.jnt_solref[0], model.jnt_solimp[0]
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
    as high as with free knees and comes to rest, one solve a step, the limits solved with
    the sand as MuJoCo's soft constraints. (Left to MuJoCo after the sand's solve, the stance
    jittered at 6 cm/s and sank 4.5 cm deeper.) With MuJoCo's solref override on, the limits
    stay MuJoCo's, and their force of the step before in the solve still holds the body
    within 2 mm/s."""
    heights = []
    for knee_range, override in ((None, False), ('0 1', False), ('0 1', True)):
        model, data, engine = _four_legs(knee_range=knee_range, override=override)
        assert len(engine.joint_limits) == (4 if knee_range and not override else 0)
        if knee_range is not None:
            data.ctrl[1::2] = -0.2
        for _ in range(1500):
            engine.step()
        solves, top = engine.solves, 0.0
        for _ in range(1000):
            engine.step()
            top = max(top, np.linalg.norm(data.qvel[:3]))
        heights.append(data.qpos[2])
        if override:
            assert top < 2e-3 and data.nefc == 4  # (MuJoCo's rows: the four knees)
        else:
            assert top < 1e-4 and engine.solves - solves == 1000 and data.nefc == 0
            assert knee_range is None or np.all(data.qpos[[8, 10, 12, 14]] < -0.01)
    assert heights[1] == pytest.approx(heights[0], abs=2e-3)
    assert heights[2] == pytest.approx(heights[0], abs=2e-3)


LIMITS = """
<mujoco><compiler angle="radian"/><option timestep="0.002" gravity="0 0 -9.81"/>
<worldbody>
  <body name="arm" pos="0 0 1"><joint name="swing" axis="0 1 0" range="-0.5 0.3"
        solreflimit="{solref}" solimplimit="{solimp}" margin="{margin}"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="0.5"/>
    <body name="slider" pos="0.3 0 0"><joint name="reach" type="slide" axis="1 0 0"
          range="-0.05 0.02" solreflimit="{solref}" solimplimit="{solimp}" margin="{margin}"/>
      <geom type="sphere" size="0.03" mass="0.2"/>
    </body>
  </body>
</worldbody></mujoco>"""


@pytest.mark.parametrize('solref, solimp, margin', [
    ('0.02 1', '0.9 0.95 0.001 0.5 2', '0'), ('0.004 0.5', '0.5 0.99 0.02 0.3 3', '0.01'),
    ('-2000 -30', '0.8 0.9 0.05 0.5 1', '0'), ('0.03 1.2', '0.95 0.95 0.001 0.5 2', '0.005')])
def test_limit_rows_are_mujocos_own(solref, solimp, margin):
    """`coupling.limit_rows` makes the rows MuJoCo makes for hinge and slide limits reached
    or within their margin: the same D and reference acceleration (efc_D, efc_aref) for
    standard and direct solref, every solimp shape, margins, both sides."""
    xml = LIMITS.format(solref=solref, solimp=solimp, margin=margin)
    model = mujoco.MjModel.from_xml_string(xml)
    model.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    data = mujoco.MjData(model)
    rng = np.random.default_rng(8)
    joints = np.array([[model.jnt_dofadr[j], model.jnt_qposadr[j]] for j in range(2)])
    params = np.zeros((2, coupling.LIMIT_PARAMS))
    params[:, :2], params[:, coupling.MARGIN] = model.jnt_range, model.jnt_margin
    params[:, coupling.SOLREF:coupling.SOLREF + 2] = model.jnt_solref
    params[:, coupling.SOLIMP:coupling.SOLIMP + 5] = model.jnt_solimp
    params[:, coupling.INVWEIGHT] = model.dof_invweight0[joints[:, 0]]
    rows = np.zeros((4, coupling.LIMIT_COLUMNS))
    compared = 0
    for qpos in ([-0.52, 0.021], [0.31, -0.06], [0.295, -0.049], [-0.5, 0.0], [0.0, 0.0]):
        data.qpos[:] = qpos
        data.qvel[:] = rng.normal(0, 0.5, 2)
        mujoco.mj_forward(model, data)
        n = coupling.limit_rows(joints, params, data.qpos, data.qvel, model.opt.timestep, True,
                                rows)
        assert n == data.nefc
        jac = data.efc_J.reshape(data.nefc, model.nv)
        for r in range(n):
            dof, sign = int(rows[r, coupling.ROW_DOF]), rows[r, coupling.ROW_SIGN]
            (match,) = [e for e in range(data.nefc) if jac[e, dof] == sign]
            assert rows[r, coupling.ROW_D] == pytest.approx(data.efc_D[match], rel=1e-12)
            assert rows[r, coupling.ROW_AREF] == pytest.approx(data.efc_aref[match], rel=1e-12,
                                                               abs=1e-12)
            compared += 1
    assert compared >= 4


def test_a_swing_onto_its_limit_in_the_air_is_mujocos():
    """No sand: an arm swinging down onto its stop and a slider hitting its end, the limits
    solved by the engine, follow MuJoCo's own limits (the same soft constraint)."""
    xml = LIMITS.format(solref='0.02 1', solimp='0.9 0.95 0.001 0.5 2', margin='0')
    own = mujoco.MjModel.from_xml_string(xml)
    own_data = mujoco.MjData(own)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    engine = SandEngine(model, data, {'slider': body_plates(model, 2, count=50)}, zeta=1.0)
    assert engine.joint_limits == ('swing', 'reach')
    for d in (own_data, data):
        d.qvel[:] = [2.0, -1.0]
    reached = set()
    for _ in range(400):
        mujoco.mj_step(own, own_data)
        engine.step()
        reached |= set(own_data.efc_id[:own_data.nefc].tolist())
        assert data.qpos == pytest.approx(own_data.qpos, abs=1e-6)
    assert reached == {0, 1} and data.nefc == 0  # (both limits met; none of them MuJoCo's)
