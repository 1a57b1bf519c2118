"""MuJoCo's constraints solved with the sand by the implicit law, as the rows MuJoCo itself
makes for them: equalities (connect, weld, joint, tendon), joint limits and contacts with
pyramidal or elliptic cones. In the air the motion is MuJoCo's own, with a dense or a sparse
constraint Jacobian, also where the solve cannot settle the rows and hands them back to
MuJoCo; in sand a robot held by a constraint (knees at their stops, joints coupled by a
stiff tendon equality, a load resting on it) stands in one solve a step. The explicit
methods leave them to MuJoCo."""
import mujoco
import numpy as np
import pytest

from rft_sim_ros.sand import elliptic_cones, layout
from rft_sim_ros.sand.engine import CONSTRAINT_ROOM, LowVelocity, SandEngine
from rft_sim_ros.sand.geoms import body_plates
from standing_body import four_legs, settle

LINKAGE = """
<mujoco><option timestep="0.002"/>
<worldbody>
  <body name="upper" pos="0 0 1"><joint name="shoulder" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="0.5"/>
    <body name="fore" pos="0.3 0 0"><joint name="elbow" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="0.3" condim="1"/>
      <body name="hand" pos="0.3 0 0"><joint name="wrist" axis="0 1 0" range="-0.2 0.2"/>
        <geom type="sphere" size="0.03" mass="0.2"/></body>
    </body>
  </body>
  <body name="strut" pos="0.6 0 1.3"><joint name="pivot" axis="0 1 0"/>
    <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.02" mass="0.4" condim="1"/>
  </body>
  <body name="lever" pos="-0.3 0 1"><joint name="spin" axis="0 1 0"/>
    <joint name="lift" type="slide" axis="0 0 1"/>
    <geom type="box" size="0.05 0.02 0.02" mass="0.3"/>
  </body>
</worldbody>
<tendon><fixed name="pair"><joint joint="shoulder" coef="1"/><joint joint="elbow" coef="0.5"/>
</fixed><fixed name="span" range="-0.05 0.05"><joint joint="pivot" coef="1"/></fixed></tendon>
<equality>
  <tendon tendon1="pair" polycoef="0.1 0 0 0 0"/>
  <joint joint1="wrist" joint2="elbow" polycoef="0 -1 0 0 0" active="false"/>
  <connect body1="strut" body2="fore" anchor="0 0 -0.3"/>
  <weld body1="lever"/>
</equality></mujoco>"""


def _own_and_engine(xml, body, jacobian=None):
    """The model stepped by MuJoCo alone, and a copy with a SandEngine (plates on `body`, far
    above the sand): (own, own_data, model, data, engine)."""
    own, model = mujoco.MjModel.from_xml_string(xml), mujoco.MjModel.from_xml_string(xml)
    if jacobian is not None:
        own.opt.jacobian = model.opt.jacobian = jacobian
    own_data, data = mujoco.MjData(own), mujoco.MjData(model)
    engine = SandEngine(model, data, {body: body_plates(model, model.body(body).id, count=50)},
                        zeta=1.0)
    return own, own_data, model, data, engine


@pytest.mark.parametrize('jacobian', [mujoco.mjtJacobian.mjJAC_DENSE,
                                      mujoco.mjtJacobian.mjJAC_SPARSE])
def test_constraints_in_the_air_move_as_mujocos_own(jacobian):
    """No sand: an arm whose joints a tendon equality couples, closed into a loop by a
    connect to a pendulum in another branch (rows that are not tree-sparse), its links
    colliding with each other and the pendulum (frictionless where a geom has condim 1), a
    wrist reaching its stops, the pendulum its tendon's range, a welded body,
    and an equality switched on halfway: everything started off its constraints and moving.
    With the rows solved by the engine (their Jacobian zeroed for MuJoCo's own solve) the
    motion is MuJoCo's, and so are the forces mjData reports for them (efc_force), with more
    rows than the engine first had room for."""
    own, own_data, model, data, engine = _own_and_engine(LINKAGE, 'hand', jacobian)
    for d in (own_data, data):
        d.qvel[:] = [1.0, -2.0, 0.5, 0.3, 0.8, 0.1]
    kinds, most = set(), 0
    for step in range(500):
        if step == 250:
            own_data.eq_active[1] = data.eq_active[1] = 1
        mujoco.mj_step(own, own_data)
        engine.step()
        assert data.qpos == pytest.approx(own_data.qpos, abs=1e-9)
        kinds |= set(own_data.efc_type.tolist())
        most = max(most, data.nefc)
        assert data.efc_force == pytest.approx(own_data.efc_force, rel=1e-6, abs=1e-6)
        assert not data.qfrc_constraint.any()  # (every row the engine's: in qfrc_passive)
    constraint = mujoco.mjtConstraint
    assert kinds == {constraint.mjCNSTR_EQUALITY, constraint.mjCNSTR_LIMIT_JOINT,
                     constraint.mjCNSTR_LIMIT_TENDON, constraint.mjCNSTR_CONTACT_FRICTIONLESS,
                     constraint.mjCNSTR_CONTACT_PYRAMIDAL}
    assert most > CONSTRAINT_ROOM and engine.solves >= 500


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
def test_a_swing_onto_its_limits_in_the_air_is_mujocos(solref, solimp, margin):
    """No sand: an arm swinging onto its stop and a slider hitting both ends, the limits
    solved by the engine, move as under MuJoCo's own limits, for standard and direct solref,
    every solimp shape and margins (a row from within the margin, not yet pushing)."""
    xml = LIMITS.format(solref=solref, solimp=solimp, margin=margin)
    own, own_data, model, data, engine = _own_and_engine(xml, 'slider')
    for d in (own_data, data):
        d.qvel[:] = [2.0, -1.0]
    reached = set()
    for _ in range(400):
        mujoco.mj_step(own, own_data)
        engine.step()
        reached |= {int(i) for i, force in zip(own_data.efc_id, own_data.efc_force) if force > 0}
        assert data.qpos == pytest.approx(own_data.qpos, abs=1e-7)  # (MuJoCo's tolerance)
    assert reached == {0, 1}  # (both joints' limits pushed)


@pytest.mark.parametrize('override', [False, True])
def test_a_body_standing_on_joints_held_at_their_stops_rests_in_sand(override):
    """The knees' servos push them 0.2 rad past their stops, which hold them: the body stands
    as high as with free knees and comes to rest in one solve a step, with MuJoCo's
    solref/solimp override on or off. (Left to MuJoCo after the sand's solve, the stance
    jittered at 6 cm/s and sank 4.5 cm deeper; with the override, solved by MuJoCo at the
    step before's force, it took about seven solves a step and crept at 2 mm/s.)"""
    model, data, engine = four_legs()
    settle(data, engine)
    free_height = data.qpos[2]
    model, data, engine = four_legs(knee='range="0 1" limited="true"', override=override)
    data.ctrl[1::2] = -0.2
    solves, unsettled, top = settle(data, engine)
    assert solves == 1000 and unsettled == 0 and top < 1e-4
    assert np.all(data.qpos[[8, 10, 12, 14]] < -0.01)  # (past the stops: the limits push)
    assert data.qpos[2] == pytest.approx(free_height, abs=2e-3)


def test_legs_coupled_by_a_stiff_tendon_equality_stand_in_sand_in_one_solve_a_step():
    """Four legs whose knee follows the hip through a stiff tendon equality (solref 5 ms, as
    dm_control's quadruped couples its leg joints), the hips servoed, standing in sand: one
    solve a step, no step unsettled, the body at rest. (Left to MuJoCo's solve after the
    sand's: 2.6 solves a step, 43 % of the steps unsettled.)"""
    extra = ('<tendon>' + ''.join(f'<fixed name="couple{i}"><joint joint="hip{i}" coef="1"/>'
                                  f'<joint joint="knee{i}" coef="0.5"/></fixed>'
                                  for i in range(4)) + '</tendon><equality>'
             + ''.join(f'<tendon tendon1="couple{i}" solref="0.005 0.5"/>' for i in range(4))
             + '</equality>')
    model, data, engine = four_legs(servos=('hip',), extra=extra)
    solves, unsettled, top = settle(data, engine)
    assert solves == 1000 and unsettled == 0 and top < 1e-4
    assert data.ne == 4 and data.qpos[2] < 0.24  # coupled, and standing in the sand
    couplings = data.qpos[[7, 9, 11, 13]] + 0.5 * data.qpos[[8, 10, 12, 14]]
    assert np.abs(couplings).max() < 1e-3  # rad: the equality holds


def test_a_load_resting_on_the_robot_stands_in_sand_in_one_solve_a_step():
    """A 2 kg ball dropped onto the torso rests there (a rigid contact between two free
    bodies) while the robot stands in sand: one solve a step, robot and ball at rest, and a
    touch sensor under the ball reads its weight. (With the contact left to MuJoCo after the
    sand's solve: 6.5 solves a step, 80 % of the steps unsettled, jitter at 1 cm/s.)"""
    ball = ('<body name="ball" pos="0 0 0.35"><freejoint/>'
            '<geom type="sphere" size="0.05" mass="2"/><site name="under" size="0.06"/></body>')
    touch = '<sensor><touch site="under"/></sensor>'
    model, data, engine = four_legs(world=ball, extra=touch)
    solves, unsettled, top = settle(data, engine)
    assert solves == 1000 and unsettled == 0 and top < 1e-4
    assert data.ncon == 1 and not data.qfrc_constraint.any()  # (the contact is the engine's)
    assert data.sensordata[0] == pytest.approx(2.0 * 9.81, rel=1e-3)  # N
    ball_z, torso_z = data.qpos[model.jnt_qposadr[-1] + 2], data.qpos[2]
    assert ball_z - torso_z == pytest.approx(0.03 + 0.05, abs=1e-3)  # on the torso
    assert np.linalg.norm(data.qvel[-6:-3]) < 1e-3  # m/s (it may roll, slowly)


SLIDING = """
<mujoco><option timestep="0.002" cone="{cone}" impratio="{impratio}" tolerance="1e-12" iterations="500"/>
<worldbody>
  <geom type="plane" size="2 2 0.1"/>
  <geom type="box" pos="1 0 0" euler="0 -20 0" size="0.3 0.3 0.02" friction="0.4"/>
  <body name="box" pos="0 0 0.05"><freejoint/>
    <geom type="box" size="0.05 0.04 0.03" mass="1" condim="{condim}"/></body>
  <body name="ball" pos="0.3 0.2 0.06"><freejoint/>
    <geom type="sphere" size="0.04" mass="0.5" condim="{condim}" friction="0.8 0.02 0.001"/>
  </body>
  <body name="puck" pos="0.95 0 0.12"><freejoint/>
    <geom type="cylinder" size="0.04 0.01" mass="0.3" condim="{condim}"/></body>
  <body name="hand" pos="0 0 20"><joint type="slide" axis="0 0 1"/>
    <geom type="sphere" size="0.02" mass="0.1" contype="0" conaffinity="0"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize('cone, condim, impratio, jacobian', [
    ('pyramidal', 3, 1, None), ('elliptic', 3, 1, None), ('elliptic', 4, 1, None),
    ('elliptic', 6, 1, None), ('elliptic', 3, 100, None), ('elliptic', 6, 100, None),
    ('elliptic', 3, 1, mujoco.mjtJacobian.mjJAC_SPARSE)])
def test_sliding_and_rolling_contacts_in_the_air_are_mujocos(cone, condim, impratio,
                                                             jacobian):
    """No sand: a box thrown spinning along a floor, a ball rolling with torsional and
    rolling friction and a puck sliding down a ramp, for both cones, every condim and a high
    impratio (as vendor scenes set), with a dense or sparse Jacobian: the rows (an elliptic
    cone's solved by Newton's method on MuJoCo's own cone law) move the bodies as MuJoCo
    does, to its solver's tolerance, over 1.2 s of contacts that stick, slide, roll and
    separate. Steps whose rows the solve cannot settle (the active set's cycles among the
    pyramids' edges, a cone whose Newton iteration has not converged in CONE_ITERATIONS
    steps) are handed back to MuJoCo's solve, and these steps too are MuJoCo's."""
    xml = SLIDING.format(cone=cone, condim=condim, impratio=impratio)
    own, own_data, model, data, engine = _own_and_engine(xml, 'hand', jacobian)
    for d in (own_data, data):
        d.qvel[0:6] = [1.0, 0.3, 0.0, 0.0, 0.0, 2.0]  # box
        d.qvel[6:9] = [-0.5, 0.8, 0.0]  # ball
        d.qvel[12:15] = [-0.4, 0.0, 0.0]  # puck
    states = set()
    for _ in range(600):
        mujoco.mj_step(own, own_data)
        engine.step()
        assert data.qpos == pytest.approx(own_data.qpos, abs=1e-5)  # m, rad
        if data.nefc == own_data.nefc:  # (what mjData reports: the solve's forces)
            assert data.efc_force == pytest.approx(own_data.efc_force, rel=1e-4, abs=1e-3)
        states |= set(own_data.efc_state.tolist())
    state = mujoco.mjtConstraintState
    assert {state.mjCNSTRSTATE_SATISFIED, state.mjCNSTRSTATE_QUADRATIC} <= states
    if cone == 'elliptic':
        assert state.mjCNSTRSTATE_CONE in states  # (sliding: the cone's middle zone)
    assert engine.handed_back_steps < 30  # (the engine's in 95 % of the steps at least)
    if cone == 'pyramidal':  # (its active set cycles in a few steps: those were MuJoCo's)
        assert engine.handed_back_steps > 0


@pytest.mark.parametrize('condim', [3, 4, 6])
def test_a_cones_force_and_hessian_are_mujocos(condim):
    """`elliptic_cones.cone_force` against MuJoCo's own mj_constraintUpdate: for an
    elliptic contact's jar in each zone (separating, sticking, sliding at random), the force
    on every row and the Hessian of the cone's cost, which MuJoCo keeps per contact."""
    xml = ('<mujoco><option cone="elliptic" impratio="3"/><worldbody>'
           '<geom type="plane" size="1 1 0.1"/><body pos="0 0 0.049"><freejoint/>'
           f'<geom type="sphere" size="0.05" condim="{condim}" friction="0.7 0.03 0.002"/>'
           '</body></worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    assert data.ncon == 1 and data.nefc == condim
    contact = data.contact[0]
    rows = np.zeros((condim, layout.ROW_COLUMNS))
    rows[:, layout.ROW_D] = data.efc_D
    rows[:, layout.ROW_FRICTION] = [contact.mu, *contact.friction[:condim - 1]]
    force, hessian = np.zeros(layout.CONE_ROWS), np.zeros((6, 6))
    zones = set()
    cones = elliptic_cones
    for jar in np.random.default_rng(5).normal(0.0, 1.0, (200, condim)):
        rows[:, layout.ROW_JAR] = jar
        zone = cones.cone_zone(rows, 0, condim, layout.ROW_JAR)
        zones.add(zone)
        cones.cone_force(rows, 0, condim, zone, layout.ROW_JAR, force, hessian)
        mujoco.mj_constraintUpdate(model, data, jar, None, 1)
        assert force[:condim] == pytest.approx(data.efc_force, rel=1e-12, abs=1e-12)
        if zone == cones.MIDDLE:
            own = data.contact.H[0][:condim * condim].reshape(condim, condim)
            assert hessian[:condim, :condim] == pytest.approx(own, rel=1e-12, abs=1e-12)
    assert zones == {cones.TOP, cones.BOTTOM, cones.MIDDLE}


@pytest.mark.parametrize('impratio, agree', [(1.0, 0.1), (100.0, 0.01)])
def test_a_foot_on_a_rigid_rock_with_elliptic_cones_rests_in_sand(impratio, agree):
    """A foot resting on a rigid rock, the others in sand, with elliptic cones: the rock's
    contact is the engine's (its force in efc_force, none in qfrc_constraint), and the body
    comes to rest as with pyramidal cones, carrying as much on the rock (up to the cones'
    shapes), in about one solve a step, also at impratio 100 as vendor scenes set it. (Left
    to MuJoCo's solve after the sand's, the cone took 4.5-7 solves a step from 2 to 5 s, and
    came to rest with almost three times the load on the rock, half as much again at
    impratio 100.)"""
    rock = '<geom name="rock" type="box" pos="0.12 0.1 -0.05" size="0.04 0.04 0.05"/>'
    loads = {}
    for cone in ('pyramidal', 'elliptic'):
        model, data, engine = four_legs(world=rock, cone=cone, impratio=impratio)
        solves, unsettled, top = settle(data, engine, land=8000)
        assert top < 1e-4 and solves < 1100
        assert data.ncon == 1 and not data.qfrc_constraint.any()  # (the engine's contact)
        normal = np.zeros(6)
        mujoco.mj_contactForce(model, data, 0, normal)
        loads[cone] = normal[0]  # N, along the contact normal
    assert loads['elliptic'] == pytest.approx(loads['pyramidal'], rel=agree)
    assert loads['elliptic'] > 1.0


def test_explicit_methods_leave_constraints_to_mujoco():
    """With `ema` or `none` the engine solves nothing but the sand: MuJoCo's rows push."""
    model = mujoco.MjModel.from_xml_string(LINKAGE)
    data = mujoco.MjData(model)
    engine = SandEngine(model, data, {'hand': body_plates(model, 3, count=50)}, zeta=1.0,
                        low_velocity=LowVelocity('none'))
    engine.step()
    assert np.abs(data.efc_force[:data.ne]).max() > 1.0
