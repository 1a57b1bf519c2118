"""A robot is simulated as its file says: a joint without an actuator stays passive, its
spring as stiff as the model says; `robot.base` welds or frees an MJCF root, or is refused
with the reason; a missing visual mesh is dropped with a notice, a missing collision mesh
refused; any keyframe is chosen by name and the default choice is printed; a robot file
and a scene file naming it start alike."""
import mujoco
import pytest

from rft_sim_ros.robot.description import DescriptionError, load_description
from rft_sim_ros.robot.pose import DEFAULT_KEYFRAMES, initial_keyframe
from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.sim.simulation import Simulation

#: A hinge arm on a post fixed to the world: `shoulder` driven by a position servo, `elbow`
#: a torsion spring (no actuator) carrying a point-like mass ARM_MASS at ARM_LENGTH.
SPRING = 40.0         # N m/rad, the elbow's stiffness as written
ARM_MASS, ARM_LENGTH = 0.5, 0.2
ARM = f"""<mujoco><compiler angle="radian"/>
  <option timestep="0.001" integrator="implicitfast"/>
  <default><geom contype="0" conaffinity="0"/></default>
  <worldbody>
    <body name="post" pos="0 0 0.5">
      <geom type="box" size="0.02 0.02 0.02" mass="1"/>
      <body name="upper">
        <joint name="shoulder" axis="0 1 0" damping="0.5"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.01" mass="0.1"/>
        <body name="forearm" pos="0 0 -0.1">
          <joint name="elbow" axis="0 1 0" stiffness="{SPRING}" damping="0.5"
                 range="-1 1"/>
          <geom type="sphere" pos="{ARM_LENGTH} 0 0" size="0.01" mass="{ARM_MASS}"/>
          <geom type="capsule" fromto="0 0 0 {ARM_LENGTH} 0 0" size="0.002" mass="1e-6"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator><position name="shoulder" joint="shoulder" kp="50" kv="1"/></actuator>
</mujoco>"""


def arm_scene(tmp_path, **overrides):
    (tmp_path / 'arm.xml').write_text(ARM)
    return load_scene(tmp_path / 'arm.xml', {'duration': 0.5, 'sand.surface_height': -1.0,
                                             'rft.sand_bodies': ['forearm'],
                                             'rft.plates_per_body': 50, **overrides})


def test_a_joint_without_an_actuator_stays_a_passive_spring_as_stiff_as_written(tmp_path):
    sim = Simulation(arm_scene(tmp_path))
    assert sim.servo_joint_names == ('shoulder',) and sim.passive_joint_names == ('elbow',)
    assert sim.commands.joint_names == ('shoulder',)  # array commands: one value
    assert any('elbow: no actuator in the model' in notice for notice in sim.notices)
    assert not [a for a in range(sim.model.nu) if 'elbow' in sim.model.actuator(a).name]
    sim.step(1500)  # the damped spring settles under the mass's weight
    m, d, joint = sim.model, sim.data, sim.model.joint('elbow').id
    forearm = m.body('forearm').id
    deflection = float(d.qpos[m.jnt_qposadr[joint]])  # (the weight turns it +y: x to -z)
    # the weight's torque about the elbow: the forearm's mass times g times the horizontal
    # lever of its centre of mass from the elbow's axis
    torque = m.body_subtreemass[forearm] * 9.81 * (d.subtree_com[forearm, 0]
                                                  - d.xanchor[joint, 0])
    assert abs(d.qvel[m.jnt_dofadr[joint]]) < 1e-3 and deflection > 0.01
    assert torque / deflection == pytest.approx(SPRING, rel=0.01)  # a servo: far stiffer
    # the scene asks for a servo on it: then it has one, and commands address it too
    served = Simulation(arm_scene(tmp_path, servos={'elbow': {'kp': 100.0, 'kd': 1.0}}))
    assert served.servo_joint_names == ('shoulder', 'elbow')
    assert served.passive_joint_names == ()


def test_servos_passive_switches_the_models_own_actuator_off(tmp_path):
    """`servos: {shoulder: passive}` on a joint the model drives with its own position
    actuator: that actuator exerts no force (gain and bias 0), so the arm swings down
    under its weight instead of being held at 0, the joint is listed passive and left out
    of commands, and a notice says which actuator was switched off."""
    held = Simulation(arm_scene(tmp_path))
    free = Simulation(arm_scene(tmp_path, servos={'shoulder': 'passive'}))
    assert free.passive_joint_names == ('shoulder', 'elbow') and free.servo_joint_names == ()
    assert ("servos passive: the model's actuator shoulder switched off (no force), so the "
            'joints they drove move freely') in free.notices, free.notices
    for sim in (held, free):
        sim.step(500)
    assert abs(held.data.joint('shoulder').qpos[0]) < 0.1  # (kp 50 against the arm's weight)
    assert free.data.joint('shoulder').qpos[0] > 0.5  # swung down
    assert free.data.actuator('shoulder').force[0] == 0.0


def test_a_model_without_actuators_gets_interfaces_on_every_joint(tmp_path):
    (tmp_path / 'bare.xml').write_text(ARM.split('<actuator>')[0] + '</mujoco>')
    sim = Simulation(load_scene(tmp_path / 'bare.xml', {'duration': 0.1,
                                                        'rft.sand_bodies': ['forearm'],
                                                        'rft.plates_per_body': 50}))
    assert sim.servo_joint_names == ('shoulder', 'elbow') and sim.passive_joint_names == ()


FREE = """<mujoco><worldbody>
  <body name="base" pos="0 0 0.3">{joints}<geom type="box" size="0.1 0.1 0.02" mass="2"/>
    <body name="leg"><joint name="hip" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.02" mass="0.3"/></body>
  </body></worldbody>
  <actuator><position joint="hip" kp="20"/></actuator></mujoco>"""


@pytest.mark.parametrize('joints, base, free_after', [
    ('<freejoint name="root"/>', 'fixed', False),
    ('<freejoint name="root"/>', 'floating', True),
    ('', 'floating', True),
    ('', 'fixed', False),
])
def test_base_welds_or_frees_an_mjcf_root(tmp_path, joints, base, free_after):
    (tmp_path / 'robot.xml').write_text(FREE.format(joints=joints))
    notices = []
    model = load_description(tmp_path / 'robot.xml', base=base,
                             log=notices.append).spec.compile()
    free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    assert bool(free) == free_after
    assert any(f'robot.base {base}: root body base' in notice for notice in notices)


def test_base_fixed_on_an_mjcf_robot_holds_it_where_the_model_puts_it(tmp_path):
    (tmp_path / 'robot.xml').write_text(FREE.format(joints='<freejoint/>'))
    sim = Simulation(load_scene(tmp_path / 'robot.xml', {'robot.base': 'fixed',
                                                         'rft.plates_per_body': 50}))
    sim.step(200)  # floating, it would fall 0.2 m in these 0.2 s
    assert sim.data.xpos[sim.model.body('base').id, 2] == pytest.approx(0.3, abs=1e-12)
    assert sim.settle_steps == 0  # spawn auto: a welded robot starts where the model puts it


def test_a_root_on_other_joints_is_refused_with_the_reason(tmp_path):
    (tmp_path / 'planar.xml').write_text(FREE.format(
        joints='<joint name="x" type="slide" axis="1 0 0"/>'))
    with pytest.raises(DescriptionError, match='root body base moves on joints x, not on one '
                                               'free joint'):
        load_description(tmp_path / 'planar.xml', base='fixed')
    with pytest.raises(SceneError, match='cannot be welded'):
        Simulation(load_scene(tmp_path / 'planar.xml', {'robot.base': 'fixed'}))


MESHES = """<mujoco><asset><mesh name="shell" file="shell.stl"/></asset>
  <worldbody><body name="base" pos="0 0 0.3"><freejoint/>
    <geom type="box" size="0.1 0.1 0.02" mass="2"/>
    <geom type="mesh" mesh="shell" {collides}/>
  </body></worldbody></mujoco>"""


def test_a_missing_visual_mesh_is_dropped_with_the_urdf_notice(tmp_path):
    (tmp_path / 'robot.xml').write_text(MESHES.format(collides='contype="0" conaffinity="0"'))
    with pytest.raises(ValueError):  # plain MuJoCo refuses the file
        mujoco.MjModel.from_xml_path(str(tmp_path / 'robot.xml'))
    notices = []
    description = load_description(tmp_path / 'robot.xml', log=notices.append)
    assert notices == [f'{tmp_path / "robot.xml"}: dropped 1 visual mesh(es) MuJoCo cannot '
                       'read (MuJoCo does not collide visuals; with rft.plate_geoms: visual '
                       'their bodies keep their collision geoms): shell.stl (missing)']
    assert description.spec.compile().ngeom == 1


def test_a_missing_collision_mesh_is_refused_naming_it(tmp_path):
    (tmp_path / 'robot.xml').write_text(MESHES.format(collides=''))
    with pytest.raises(DescriptionError, match=r'mesh shell: file shell\.stl not found'):
        load_description(tmp_path / 'robot.xml')


KEYS = """<mujoco><compiler angle="radian"/><worldbody><body name="base" pos="0 0 0.3"><freejoint/>
  <geom type="box" size="0.1 0.1 0.02" mass="2"/>
  <body name="leg"><joint name="hip" axis="0 1 0" range="-1 1"/>
    <geom type="capsule" fromto="0 0 0 0 0 -0.2" size="0.02" mass="0.3"/></body>
  </body></worldbody>
  <actuator><position joint="hip" kp="20"/></actuator>
  <keyframe>{keys}</keyframe></mujoco>"""


def _model(keys):
    return mujoco.MjModel.from_xml_string(KEYS.format(keys=keys))


def test_the_default_keyframe_is_the_first_standing_name_else_the_first_keyframe():
    assert DEFAULT_KEYFRAMES == ('home', 'stand', 'standing', 'default')
    assert initial_keyframe(_model('<key name="crouch"/><key name="stand"/>')) == 'stand'
    assert initial_keyframe(_model('<key name="standing"/><key name="home"/>')) == 'home'
    assert initial_keyframe(_model('<key name="crouch"/><key name="sit"/>')) == 'crouch'
    assert initial_keyframe(_model('<key/>')) == 0          # unnamed: by its id
    assert initial_keyframe(_model('<key name="a"/>'), '') is None  # '': the qpos0
    assert initial_keyframe(mujoco.MjModel.from_xml_string(
        KEYS.format(keys='').replace('<keyframe></keyframe>', ''))) is None


def test_any_keyframe_is_chosen_by_name_and_the_default_is_printed(tmp_path):
    (tmp_path / 'robot.xml').write_text(KEYS.format(
        keys='<key name="crouch" qpos="0 0 0.3 1 0 0 0 -0.5"/>'
             '<key name="stand" qpos="0 0 0.3 1 0 0 0 0.5"/>'))
    path = tmp_path / 'robot.xml'
    hip = 7  # qpos address of the hip (after the free joint's 7)
    chosen = Simulation(load_scene(path, {'robot.spawn': 'model', 'rft.plates_per_body': 50}))
    assert chosen.data.qpos[hip] == 0.5
    notice = next(n for n in chosen.notices if n.startswith('initial pose'))
    assert "keyframe 'stand'" in notice and 'home, stand, standing, default' in notice
    assert 'it has crouch, stand' in notice
    named = Simulation(load_scene(path, {'robot.keyframe': 'crouch', 'robot.spawn': 'model',
                                         'rft.plates_per_body': 50}))
    assert named.data.qpos[hip] == -0.5
    assert not [n for n in named.notices if n.startswith('initial pose')]


def test_a_robot_file_and_a_scene_naming_it_start_alike(tmp_path):
    (tmp_path / 'robot.xml').write_text(FREE.format(joints='<freejoint/>'))
    (tmp_path / 'scene.yaml').write_text('model: robot.xml\n')
    bare, named = load_scene(tmp_path / 'robot.xml'), load_scene(tmp_path / 'scene.yaml')
    differ = {key for key in bare.values if bare.values[key] != named.values[key]}
    assert differ == {'name', 'description', 'model'}  # (model: resolved, or as given)
    assert bare.model_path == named.model_path
    assert bare.values['robot.spawn'] == 'auto' and bare.scenario == 'external'


def test_joint_states_report_the_passive_joint_and_array_commands_leave_it_out(tmp_path):
    """The node's paths (ROS-free runtime): /joint_states (and the bag's, the same states)
    list every named joint, the passive one too; a position array has one value per
    commanded joint, `joint_names` order."""
    from ros_test_support import Harness, position_array
    harness = Harness(arm_scene(tmp_path))
    assert harness.runtime.joint_names == ('shoulder',)
    harness.runtime.tick()
    assert harness.sink.states[0].joint_names == ('shoulder', 'elbow')
    harness.runtime.on_positions(position_array([0.3]))
    assert harness.targets().tolist() == [0.3]
    harness.runtime.on_positions(position_array([0.3, 0.0]))  # (the passive joint: no)
    assert harness.targets().tolist() == [0.3] and harness.warnings


#: A parallelogram linkage under a post fixed to the world: the crank driven by a position
#: servo, the rocker and the coupler's hinge passive, the loop closed by a connect equality
#: between the coupler's end and the rocker's.
LOOP = """<mujoco><compiler angle="radian"/>
  <option timestep="0.001" integrator="implicitfast"/>
  <default><geom contype="0" conaffinity="0"/><joint axis="0 1 0" damping="0.05"/></default>
  <worldbody><body name="post" pos="0 0 0.5"><geom type="box" size="0.2 0.02 0.02" mass="1"/>
    <body name="crank"><joint name="crank"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.005" mass="0.05"/>
      <body name="coupler" pos="0 0 -0.1"><joint name="coupler_hinge"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.005" mass="0.1"/></body></body>
    <body name="rocker" pos="0.2 0 0"><joint name="rocker"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.1" size="0.005" mass="0.05"/></body>
  </body></worldbody>
  <equality><connect body1="coupler" body2="rocker" anchor="0.2 0 0"/></equality>
  <actuator><position name="crank" joint="crank" kp="20" kv="0.5"/></actuator>
</mujoco>"""


def test_a_closed_loop_is_kept_and_its_unactuated_joints_follow_it(tmp_path):
    (tmp_path / 'loop.xml').write_text(LOOP)
    sim = Simulation(load_scene(tmp_path / 'loop.xml', {
        'rft.sand_bodies': ['coupler'], 'rft.plates_per_body': 50, 'sand.surface_height': -1.0}))
    assert sim.model.neq == 1 and sim.model.eq_active0[0]
    assert sim.servo_joint_names == ('crank',)
    assert set(sim.passive_joint_names) == {'coupler_hinge', 'rocker'}
    assert sim.commands.set_positions([0.3], now=sim.time).accepted
    sim.step(1000)
    m, d = sim.model, sim.data
    angle = {name: float(d.qpos[m.jnt_qposadr[m.joint(name).id]])
             for name in ('crank', 'rocker', 'coupler_hinge')}
    assert angle['crank'] == pytest.approx(0.3, abs=0.02)
    assert angle['rocker'] == pytest.approx(angle['crank'], abs=2e-3)  # a parallelogram
    assert angle['coupler_hinge'] == pytest.approx(-angle['crank'], abs=2e-3)


def test_servos_passive_switches_off_a_muscle_too():
    """A muscle on a joint made passive: its gain is its own kind (not a number to zero),
    so it is made a fixed gain of 0 with no bias; the model compiles and it pushes nothing."""
    from rft_sim_ros.robot.joints import add_joint_interfaces
    spec = mujoco.MjSpec.from_string(
        '<mujoco><worldbody><body><joint name="j" axis="0 1 0"/><geom size="0.1" mass="1"/>'
        '</body></worldbody><actuator><muscle name="m" joint="j"/></actuator></mujoco>')
    plan = add_joint_interfaces(spec, {'j': 'passive'})
    assert plan.passive == ('j',) and plan.switched_off == ('m',) and plan.commanded == ()
    model = spec.compile()
    data = mujoco.MjData(model)
    data.ctrl[:], data.act[:] = 1.0, 1.0
    mujoco.mj_step(model, data)
    assert data.actuator_force[0] == 0.0


def test_a_velocity_actuated_joint_is_named_and_servos_gives_it_commands(tmp_path):
    """A shoulder the model drives with a <velocity> actuator: no command interfaces (its
    control stays 0: held still), a notice names it and says how to give it a servo, and
    the reason commands cannot reach it names it; `servos` naming it switches that actuator
    off and gives it a PD and a motor, so a velocity command turns it; a servos pattern
    that matches no joint is refused, naming the joints."""
    velocity = ARM.replace('<position name="shoulder" joint="shoulder" kp="50" kv="1"/>',
                           '<velocity name="spin" joint="shoulder" kv="5" ctrlrange="-20 20"/>')
    (tmp_path / 'arm.xml').write_text(velocity)
    settings = {'duration': 0.5, 'sand.surface_height': -1.0, 'rft.sand_bodies': ['forearm'],
                'rft.plates_per_body': 50}
    held = Simulation(load_scene(tmp_path / 'arm.xml', settings))
    assert held.servo_joint_names == () and held.commands is None
    assert any(n.startswith("joint shoulder: driven by the model's own actuators of another "
                            'kind') for n in held.notices), held.notices
    assert "driven by the model's own actuators of another kind: shoulder" in \
        held.no_commands_reason()
    served = Simulation(load_scene(tmp_path / 'arm.xml', {
        **settings, 'servos': {'shoulder': {'kp': 20.0, 'kd': 0.5}}}))
    assert served.servo_joint_names == ('shoulder',)
    assert any("actuator spin of another kind than position or motor switched off" in n
               for n in served.notices)
    assert served.interfaces.gains['shoulder'].effort == float('inf')  # (not the actuator's
    # control range, a speed)
    effort = served.interfaces.effort_actuators[0]
    assert served.model.actuator(effort).name == 'effort_shoulder'
    served.commands.set_velocities([2.0], served.time)
    served.step(200)
    start = served.data.joint('shoulder').qpos[0]
    served.step(1000)  # (1 s: its mean speed, the weight's pull round a turn aside)
    assert served.data.actuator('spin').force[0] == 0.0
    assert served.data.joint('shoulder').qpos[0] - start == pytest.approx(2.0, rel=0.05)
    with pytest.raises(SceneError, match=r"servos: 'shuolder' matches no joint of the model "
                                         r'\(its joints: shoulder, elbow\)'):
        Simulation(load_scene(tmp_path / 'arm.xml', {**settings,
                                                     'servos': {'shuolder': 'passive'}}))
