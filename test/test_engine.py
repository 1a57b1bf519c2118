"""SandEngine: kinematics, culling, forces vs the reference law, low-velocity treatments."""
import mujoco
import numpy as np
import pytest
from numba import njit

from rft_sim_ros.rft import body_wrench
from rft_sim_ros.rft import kernel
from rft_sim_ros.sand import engine as engine_module
from rft_sim_ros.sand import layout, mujoco_terms, tree_solve
from rft_sim_ros.sand.engine import LowVelocity, SandEngine
from rft_sim_ros.sand.geoms import body_plates

ARM = """
<mujoco><option timestep="0.001" integrator="implicitfast"/>
<worldbody>
  <body name="base" pos="0 0 0.3"><freejoint/>
    <geom type="box" size="0.1 0.05 0.02" mass="2"/>
    <body name="upper" pos="0.1 0 0"><joint name="hip" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.1 0 -0.1" size="0.01" mass="0.2"/>
      <body name="lower" pos="0.1 0 -0.1"><joint name="knee" type="ball"/>
        <geom type="capsule" fromto="0 0 0 0 0.05 -0.15" size="0.008" mass="0.1"/>
        <body name="fixed_tip" pos="0 0.05 -0.15"><geom type="sphere" size="0.01" mass="0.01"/></body>
      </body>
    </body>
  </body>
</worldbody></mujoco>"""


def _arm(**engine_options):
    model = mujoco.MjModel.from_xml_string(ARM)
    data = mujoco.MjData(model)
    plates = {name: body_plates(model, model.body(name).id, count=300)
              for name in ('upper', 'lower', 'fixed_tip')}
    return model, data, SandEngine(model, data, plates, zeta=2.0, **engine_options)


def _random_state(model, data, seed):
    rng = np.random.default_rng(seed)
    data.qpos[:3] = [0.0, 0.0, 0.22]
    quat = rng.normal(size=4)
    data.qpos[3:7] = quat / np.linalg.norm(quat) * np.sign(quat[0])
    data.qpos[3:7] = 0.9 * np.array([1, 0, 0, 0]) + 0.1 * data.qpos[3:7]
    data.qpos[3:7] /= np.linalg.norm(data.qpos[3:7])
    data.qpos[7] = rng.uniform(-0.5, 0.5)
    ball = rng.normal(size=4) * 0.2 + [1, 0, 0, 0]
    data.qpos[8:12] = ball / np.linalg.norm(ball)
    data.qvel[:] = rng.normal(size=model.nv) * 0.3


@pytest.mark.parametrize('seed', range(5))
def test_slot_jacobians_and_free_force_match_mujoco(seed):
    model, data, engine = _arm()
    _random_state(model, data, seed)
    mujoco.mj_forward(model, data)
    bodies = np.arange(len(engine.body_ids))
    jac = np.zeros((6 * len(bodies) + 1, model.nv))
    chain = np.zeros((len(bodies), model.nv), dtype=np.int64)
    chain_count = np.zeros(len(bodies), dtype=np.int64)
    mujoco_terms.prepare_solve(len(bodies), bodies, engine.body_ids, data.xipos, data.subtree_com,
                           data.cdof, model.body_rootid, model.body_dofnum, model.body_dofadr,
                           model.body_parentid, model.dof_parentid, data.qfrc_passive,
                           data.qfrc_actuator, data.qfrc_applied, data.qfrc_constraint,
                           data.qfrc_bias, jac, chain, chain_count)
    free_force = (data.qfrc_passive + data.qfrc_actuator + data.qfrc_applied
                  + data.qfrc_constraint - data.qfrc_bias)
    assert np.allclose(jac[-1], free_force)
    for slot, body in enumerate(engine.body_ids):
        jacp, jacr = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        mujoco.mj_jac(model, data, jacp, jacr, data.xipos[body], body)
        assert np.allclose(jac[6 * slot:6 * slot + 3], jacp, atol=1e-12)
        assert np.allclose(jac[6 * slot + 3:6 * slot + 6], jacr, atol=1e-12)
        reached = np.flatnonzero(np.any(np.vstack([jacp, jacr]) != 0.0, axis=0))
        assert sorted(chain[slot, :chain_count[slot]]) == list(reached)  # the kinematic chain


TREE = """
<mujoco><worldbody>
  <body name="base" pos="0 0 0.3"><freejoint/><geom type="box" size="0.1 0.05 0.02" mass="2"/>
    <body name="left" pos="0.1 0.05 0"><joint type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.1 0 -0.1" size="0.01" mass="0.2"/>
      <body name="left_tip" pos="0.1 0 -0.1"><joint type="ball"/>
        <geom type="sphere" size="0.02" pos="0 0.03 -0.05" mass="0.1"/></body></body>
    <body name="right" pos="-0.1 -0.05 0"><joint type="hinge" axis="1 0 0"/>
      <geom type="capsule" fromto="0 0 0 -0.1 0 -0.1" size="0.01" mass="0.3"/>
      <body name="right_tip" pos="-0.1 0 -0.1"><joint type="slide" axis="0 0 1"/>
        <geom type="sphere" size="0.02" mass="0.05"/></body></body>
  </body>
</worldbody></mujoco>"""


@pytest.mark.parametrize('seed', range(3))
def test_translational_inverse_masses_match_a_dense_inverse(seed):
    """The tree (no fill-in) factorisation of Mh = M + D on a branched robot: the slots'
    translational inverse effective masses equal trace(J_t Mh^-1 J_t^T) from numpy."""
    model = mujoco.MjModel.from_xml_string(TREE)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    data.qpos[7:] = rng.normal(size=model.nq - 7) * 0.5
    data.qpos[10:14] /= np.linalg.norm(data.qpos[10:14])  # the ball joint's quaternion
    mujoco.mj_forward(model, data)
    mass = np.zeros((model.nv, model.nv))
    full_inertia, arguments = engine_module.full_inertia_call(model, data, mass)
    full_inertia(*arguments)
    mass += np.diag(rng.uniform(0.0, 0.1, model.nv))
    bodies = ['left', 'left_tip', 'right', 'right_tip', 'base']
    jac = np.zeros((6 * len(bodies) + 1, model.nv))
    for slot, name in enumerate(bodies):
        body = model.body(name).id
        mujoco.mj_jac(model, data, jac[6 * slot:6 * slot + 3], jac[6 * slot + 3:6 * slot + 6],
                      data.xipos[body], body)
    out = np.zeros(len(bodies))
    tree_solve.translational_inverse_masses(mass, model.dof_parentid, jac, len(bodies),
                                           np.empty_like(mass), np.empty((model.nv, 15)), out)
    inverse = np.linalg.inv(mass)
    expected = [np.trace(jac[6 * s:6 * s + 3] @ inverse @ jac[6 * s:6 * s + 3].T)
                for s in range(len(bodies))]
    assert np.allclose(out, expected, rtol=1e-12, atol=0)


@pytest.mark.parametrize('seed', range(3))
def test_tree_solve_matches_numpy_on_a_branched_robot(seed):
    """The implicit system Mh - dt J^T K J (K non-symmetric, per body) of a branched robot
    keeps the inertia's tree sparsity; eliminating from the leaves without pivoting solves it
    as numpy does, and the checked solve keeps that result."""
    model = mujoco.MjModel.from_xml_string(TREE)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    data.qpos[7:] = rng.normal(size=model.nq - 7) * 0.5
    data.qpos[10:14] /= np.linalg.norm(data.qpos[10:14])
    mujoco.mj_forward(model, data)
    system = np.zeros((model.nv, model.nv))
    full_inertia, arguments = engine_module.full_inertia_call(model, data, system)
    full_inertia(*arguments)
    for name in ('left_tip', 'right_tip', 'base'):
        body = model.body(name).id
        jac = np.zeros((6, model.nv))
        mujoco.mj_jac(model, data, jac[:3], jac[3:], data.xipos[body], body)
        system += 1e-3 * jac.T @ rng.normal(size=(6, 6)) @ jac
    assert np.all((system != 0) <= (np.abs(_ancestry(model)) > 0))  # the tree's pattern
    rhs = rng.normal(size=model.nv)
    expected = np.linalg.solve(system, rhs)
    tree = rhs.copy()
    assert tree_solve.tree_solve(system.copy(), tree, model.dof_parentid)
    assert np.allclose(tree, expected, rtol=1e-10, atol=1e-12)
    solution = np.empty(model.nv)
    kept = system.copy()
    tree_solve.checked_solve(kept, rhs, model.dof_parentid, np.empty_like(system), solution)
    assert np.array_equal(solution, tree) and np.array_equal(kept, system)


def _ancestry(model):
    """(nv, nv) 1 where one dof is the other's ancestor or itself, else 0."""
    related = np.eye(model.nv)
    for dof in range(model.nv):
        parent = model.dof_parentid[dof]
        while parent >= 0:
            related[dof, parent] = related[parent, dof] = 1
            parent = model.dof_parentid[parent]
    return related


@njit(fastmath=True)
def _checked_solve_in_fastmath(matrix, rhs, dof_parentid, factored, solution):
    """The checked solve as the step calls it: from a kernel compiled with fastmath."""
    return tree_solve.checked_solve(matrix, rhs, dof_parentid, factored, solution)


@pytest.mark.parametrize('leaf_pivot', [0.0, 1e-8, 0.5])
def test_checked_solve_pivots_where_the_leaves_first_elimination_fails(leaf_pivot):
    """A zero, small or fair pivot for the leaf of a well-conditioned system: the unpivoted
    elimination stops at the zero one and loses ~1e-9 to growth at the small one, where the
    checked solve (also called from a fastmath kernel, as the step calls it) falls back to
    partial pivoting and gets numpy's answer; at the fair one it keeps the tree solve's."""
    parents = np.array([-1, 0, 1], dtype=np.int32)  # a chain: 0 <- 1 <- 2
    system = np.array([[2.0, 1.0, 1.0], [1.0, 3.0, 1.0], [1.0, 1.0, leaf_pivot]])
    rhs = np.array([1.0, -2.0, 0.5])
    expected = np.linalg.solve(system, rhs)
    tree = rhs.copy()
    done = tree_solve.tree_solve(system.copy(), tree, parents)
    tree_error = np.max(np.abs(tree - expected)) / np.max(np.abs(expected))
    assert done == (leaf_pivot > 0)
    assert (tree_error > 1e-10) == (leaf_pivot < 0.1)
    for solve in (_checked_solve_in_fastmath, tree_solve.checked_solve):
        solution = np.empty(3)
        solve(system, rhs, parents, np.empty((3, 3)), solution)
        assert np.max(np.abs(solution - expected)) < 1e-15 * np.max(np.abs(expected))
        assert np.array_equal(solution, tree) == (leaf_pivot == 0.5)


@pytest.mark.parametrize('seed', range(3))
def test_explicit_engine_wrench_equals_the_reference_law(seed):
    """Plate kinematics from MuJoCo's com-based velocities + compiled law == body_wrench."""
    model, data, engine = _arm(low_velocity=LowVelocity(method='none'))
    _random_state(model, data, seed)
    mujoco.mj_step1(model, data)
    engine.apply()
    assert engine.plates_active > 0
    for i, name in enumerate(engine.body_names):
        body = model.body(name).id
        velocity = np.zeros(6)  # [omega; v] of the body origin, world axes
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, body, velocity, 0)
        plates = body_plates(model, body, count=300)
        force, torque = body_wrench(plates, data.xpos[body], data.xmat[body].reshape(3, 3),
                                    velocity[3:], velocity[:3], 2.0)
        torque_about_com = torque + np.cross(data.xpos[body] - data.xipos[body], force)
        assert np.allclose(engine.body_wrenches[i, :3], force, rtol=1e-9, atol=1e-12)
        assert np.allclose(engine.body_wrenches[i, 3:], torque_about_com, rtol=1e-9, atol=1e-12)
        assert np.allclose(data.xfrc_applied[body], engine.body_wrenches[i])


BLADE = """
<mujoco><option timestep="0.001"/>
<worldbody><body name="blade"><freejoint/><geom type="box" size="0.03 0.01 0.002"/></body>
</worldbody></mujoco>"""


@pytest.mark.parametrize('seed', range(4))
def test_plates_sliding_in_their_own_plane_never_lead(seed):
    """A blade turning about its long axis, tilted at random: its end faces move in their own
    plane (n . v = 0 up to rounding) and must feel nothing, whatever the rounding's sign."""
    model = mujoco.MjModel.from_xml_string(BLADE)
    data = mujoco.MjData(model)
    engine = SandEngine(model, data, {'blade': body_plates(model, 1, count=400)}, zeta=2.0,
                        low_velocity=LowVelocity(method='none'))
    rng = np.random.default_rng(seed)
    quat = rng.normal(size=4)
    data.qpos[3:7] = quat / np.linalg.norm(quat)
    data.qvel[3:6] = [2.0, 0.0, 0.0]  # rad/s about the blade's long axis (free joint: local)
    mujoco.mj_step1(model, data)
    engine.apply()
    gathered = engine._counters[layout.GATHERED]
    end_faces = np.abs(engine.local_normal[engine._plate[:gathered], 0]) > 0.999
    assert engine.plates_active > 0 and not end_faces.any()
    table = engine._table[:, :gathered]
    n_v = (table[kernel.NORMAL:kernel.NORMAL + 3]
           * table[kernel.DIRECTION:kernel.DIRECTION + 3]).sum(axis=0)
    assert (n_v > 1e-6).all()


def test_bodies_above_the_sand_are_skipped_and_cost_nothing():
    model, data, engine = _arm()
    data.qpos[2] = 2.0
    data.qvel[:3] = [0.0, 0.0, -1.0]
    mujoco.mj_step1(model, data)
    engine.apply()
    assert engine.plates_active == 0 and engine._counters[layout.SLOTS] == 0
    assert not data.xfrc_applied.any()


def test_fast_motion_gets_the_full_rft_force_with_the_implicit_treatment():
    explicit = _arm(low_velocity=LowVelocity(method='none'))
    implicit = _arm()
    for model, data, engine in (explicit, implicit):
        _random_state(model, data, 3)
        data.qvel[2] = -0.5  # intruding fast: the sand cannot stop it within a step
        mujoco.mj_step1(model, data)
        engine.apply()
    assert np.allclose(implicit[2].body_wrenches, explicit[2].body_wrenches, rtol=1e-12)


def test_zeta_change_applies_on_the_next_step():
    model, data, engine = _arm(low_velocity=LowVelocity(method='none'))
    _random_state(model, data, 1)
    mujoco.mj_step1(model, data)
    engine.apply()
    before = engine.body_wrenches.copy()
    engine.zeta = 4.0
    engine.apply()
    assert np.allclose(engine.body_wrenches, 2 * before, rtol=1e-12)
    with pytest.raises(ValueError, match='zeta must be'):
        engine.zeta = float('nan')
    assert engine.zeta == 4.0


def test_ema_history_is_dropped_when_a_plate_leaves_the_sand():
    model, data, engine = _arm(low_velocity=LowVelocity(method='ema', ema_alpha=0.25))
    _random_state(model, data, 2)
    data.qvel[:] = 0.0
    data.qvel[2] = -0.3
    mujoco.mj_step1(model, data)
    engine.apply()
    raw = engine.body_wrenches.copy()  # first step in the sand: no history, raw force
    engine.apply()
    assert np.allclose(engine.body_wrenches, raw)  # same state: smoothed == raw again
    data.qpos[2] = 2.0  # out of the sand for a step: history must go
    mujoco.mj_step1(model, data)
    engine.apply()
    assert engine.plates_active == 0
    data.qpos[2] = 0.22
    data.qvel[2] = -0.6
    mujoco.mj_step1(model, data)
    engine.apply()
    fresh = SandEngine(model, data, {n: body_plates(model, model.body(n).id, count=300)
                                     for n in engine.body_names}, zeta=2.0,
                       low_velocity=LowVelocity(method='none'))
    fresh.apply()
    assert np.allclose(engine.body_wrenches, fresh.body_wrenches)


@pytest.mark.parametrize('method', ['ema', 'implicit'])
def test_after_forget_last_step_a_step_is_the_first_steps(method):
    """A reset's state does not follow the last step: after `forget_last_step` the step
    from it is what an engine's first step from it is, to the bit (neither the EMA's
    history nor the solve's start sets of the steps before reach it)."""
    def start(model, data):
        mujoco.mj_resetData(model, data)
        _random_state(model, data, 4)
        data.qvel[2] = -0.05  # slowly into the sand: its history matters

    runs = []
    for history in (0, 30):
        model, data, engine = _arm(low_velocity=LowVelocity(method=method))
        start(model, data)
        for _ in range(history):
            engine.step()
        start(model, data)
        engine.forget_last_step()
        solves = engine.solves
        engine.step()
        runs.append((engine.body_wrenches.copy(), data.qvel.copy(), engine.solves - solves))
    (wrench, qvel, solves), (wrench_after, qvel_after, solves_after) = runs
    assert np.abs(wrench).max() > 1.0  # in the sand
    assert np.array_equal(wrench_after, wrench) and np.array_equal(qvel_after, qvel)
    assert solves_after == solves


def test_rk4_and_bad_low_velocity_settings_are_refused():
    model = mujoco.MjModel.from_xml_string(ARM)
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    with pytest.raises(ValueError, match='RK4'):
        SandEngine(model, mujoco.MjData(model), {}, zeta=1.0)
    with pytest.raises(ValueError, match='method'):
        LowVelocity(method='magic')
    with pytest.raises(ValueError, match='ema_alpha'):
        LowVelocity(method='ema', ema_alpha=0.0)


DAMPED = """
<mujoco><option timestep="0.002" integrator="{integrator}"/>
<worldbody><body name="base" pos="0 0 0.3"><freejoint/><geom type="box" size="0.05 0.05 0.02" mass="1"/>
  <body name="arm"><joint name="hinge" type="hinge" axis="0 1 0" damping="0.8"/>
    <geom type="capsule" fromto="0 0 0 0.1 0 0" size="0.005" mass="0.01"/>
    <body name="tip" pos="0.1 0 0"><joint name="slide" type="slide" axis="1 0 0" damping="3"/>
      <geom type="sphere" size="0.01" mass="0.01"/></body></body></body></worldbody>
<actuator><velocity joint="hinge" kv="2"/><position joint="slide" kp="50" kv="4"/>
  <position joint="slide" kp="50" forcerange="-0.001 0.001"/></actuator></mujoco>"""


@pytest.mark.parametrize('integrator', ['implicitfast', 'implicit', 'Euler'])
def test_predicted_end_velocity_matches_mujocos_step(integrator):
    """Without sand, qvel + dt (M + dt D)^-1 tau_free is exactly what mj_step2 integrates
    (joint damping and actuator velocity gains implicit, clamped actuators excluded); the
    sand solve builds on this prediction, with Mh = M + dt D from implicit_mass."""
    model = mujoco.MjModel.from_xml_string(DAMPED.format(integrator=integrator))
    data = mujoco.MjData(model)
    plates = {'tip': body_plates(model, model.body('tip').id, count=50)}
    engine = SandEngine(model, data, plates, zeta=1.0)
    data.qvel[:] = np.linspace(-0.5, 0.7, model.nv)
    data.ctrl[:] = [1.5, 0.02, 0.5]
    mujoco.mj_step1(model, data)
    mujoco.mj_fwdActuation(model, data)
    rows = np.zeros((1, model.nv))
    rows[0] = data.qfrc_passive + data.qfrc_actuator + data.qfrc_applied - data.qfrc_bias
    m, d = model, data
    settings = engine._settings  # as the engine found them for this model
    damper, actuators = settings[layout.DAMPER] != 0, settings[layout.ACTUATORS] != 0
    mujoco_terms.implicit_damping(damper, actuators, m.dof_damping, m.actuator_trntype,
                              m.actuator_trnid, m.actuator_gear, m.jnt_type, m.jnt_dofadr,
                              m.actuator_dyntype, m.actuator_gaintype, m.actuator_gainprm,
                              m.actuator_biastype, m.actuator_biasprm, m.actuator_forcelimited,
                              m.actuator_forcerange, d.ctrl, d.act, m.actuator_actadr,
                              d.actuator_force, engine._damping)
    assert engine._damping.any()
    mass = np.zeros((model.nv, model.nv))
    function, args = engine_module.full_inertia_call(model, data, mass)
    function(*args)
    mujoco_terms.implicit_mass(mass, engine._damping, model.opt.timestep)
    predicted = data.qvel + model.opt.timestep * np.linalg.solve(mass, rows[0])
    mujoco.mj_step2(model, data)
    tolerance = 1e-3 if integrator == 'implicit' else 1e-10  # 'implicit' adds Coriolis terms
    assert np.allclose(data.qvel, predicted, rtol=tolerance, atol=tolerance)
