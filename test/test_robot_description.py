"""Robot descriptions in: xacro URDF with $(find) includes, package:// meshes (OBJ, COLLADA),
<ros2_control>/<gazebo> tags and a fixed root link; MJCF; robot_description strings; errors.

Test robot: test/robots/sandbot_description (8 DOF, feet `*_foot` joined to the calves by
fixed joints, root link `base` fixed to `trunk`).
"""
import shutil
from pathlib import Path

import mujoco
import numpy as np
import pytest

from rft_sim_ros.robot import DescriptionError, load_description
from rft_sim_ros.robot.description import FLOATING_JOINT
from rft_sim_ros.robot.xacro_files import expand_xacro
from rft_sim_ros.robot.packages import PackageResolver
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation

PACKAGE = Path(__file__).parent / 'robots' / 'sandbot_description'
XACRO = PACKAGE / 'urdf' / 'sandbot.urdf.xacro'
PATHS = {'sandbot_description': PACKAGE}
JOINTS = [f'{leg}_{j}' for leg in ('fl', 'fr', 'rl', 'rr') for j in ('hip', 'knee')]


@pytest.fixture(scope='module')
def sandbot():
    return load_description(XACRO, package_paths=PATHS, log=lambda notice: None)


def test_xacro_urdf_loads_with_floating_base_and_named_links(sandbot):
    model = sandbot.spec.compile()
    assert sandbot.kind == 'urdf' and sandbot.source_path == XACRO
    bodies = {model.body(i).name for i in range(model.nbody)}
    assert {'base', 'trunk', 'fl_foot', 'rr_calf'} <= bodies  # fixed-joint links kept
    free = model.joint(FLOATING_JOINT)
    assert model.jnt_type[free.id] == mujoco.mjtJoint.mjJNT_FREE
    assert model.body(model.jnt_bodyid[free.id]).name == 'base'
    hinges = [model.joint(j).name for j in range(model.njnt)
              if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    assert hinges == JOINTS
    # URDF masses: trunk 3 kg + 4 x (0.2 + 0.1) kg; massless base and feet
    assert model.body_subtreemass[model.body('base').id] == pytest.approx(4.2)
    assert model.body_mass[model.body('fl_foot').id] == 0.0


def test_limits_and_ros2_control_initial_values_are_read(sandbot):
    assert sandbot.effort_limits == {name: 12.0 for name in JOINTS}
    assert sandbot.velocity_limits == {name: 12.0 for name in JOINTS}
    assert sandbot.initial_positions == {
        name: (0.4 if name.endswith('hip') else -0.8) for name in JOINTS}
    model = sandbot.spec.compile()
    assert model.jnt_range[model.joint('fl_knee').id] == pytest.approx([-2.5, 0.0])


def test_meshes_resolved_visual_dae_dropped_collision_dae_converted(sandbot):
    model = sandbot.spec.compile()
    trunk = model.body('trunk').id
    trunk_geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == trunk]
    assert [model.geom_type[g] for g in trunk_geoms] == [mujoco.mjtGeom.mjGEOM_BOX]
    foot = model.body('fl_foot').id
    foot_meshes = [g for g in range(model.ngeom) if model.geom_bodyid[g] == foot
                   and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH]
    assert len(foot_meshes) == 1  # package:// OBJ, collision
    thigh = model.body('fl_thigh').id
    thigh_mesh = [model.geom_dataid[g] for g in range(model.ngeom)
                  if model.geom_bodyid[g] == thigh][0]
    vertices = model.mesh_vert[model.mesh_vertadr[thigh_mesh]:
                               model.mesh_vertadr[thigh_mesh] + model.mesh_vertnum[thigh_mesh]]
    # the COLLADA box (0.03 x 0.03 x 0.12 m) arrives with its size (centred by MuJoCo)
    assert np.ptp(vertices, axis=0) == pytest.approx([0.03, 0.03, 0.12], abs=1e-6)
    notices = ' | '.join(sandbot.notices)
    assert 'ignored <gazebo>, <ros2_control>' in notices
    assert 'dropped 1 visual mesh' in notices and 'trunk_visual.dae' in notices
    assert 'converted 1 collision mesh' in notices and 'thigh.dae' in notices
    assert len(sandbot.notices) == 3  # once each, not once per leg


def test_notices_are_logged_once():
    logged = []
    load_description(XACRO, package_paths=PATHS, log=logged.append)
    assert len(logged) == 3


def test_fixed_base_welds_the_root_link():
    model = load_description(XACRO, package_paths=PATHS, base='fixed',
                             log=lambda notice: None).spec.compile()
    assert model.nq == len(JOINTS) and model.nv == len(JOINTS)


WORLD_FLOATING = """<robot name="w">
  <link name="world"/>
  <joint name="floating_base_joint" type="floating">
    <parent link="world"/><child link="base"/>
  </joint>
  <link name="base"><inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01"
    ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><box size="0.2 0.1 0.05"/></geometry></collision></link>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="leg"/>
    <origin xyz="0 0 -0.1"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="5" velocity="5"/></joint>
  <link name="leg"><inertial><mass value="0.2"/><inertia ixx="0.001" iyy="0.001" izz="0.001"
    ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><sphere radius="0.03"/></geometry></collision></link>
</robot>"""


def test_a_root_hung_from_world_by_a_floating_joint_keeps_that_free_joint(tmp_path):
    """As vendors' URDFs for MuJoCo have it (Unitree's AS2, its B2 for MuJoCo): that joint
    is the free base (a second one failed: more than 6 dofs); `fixed` drops it. A robot file
    with a fixed base starts where the model puts it (spawn auto: rest needs a free base)."""
    path = tmp_path / 'w.urdf'
    path.write_text(WORLD_FLOATING)
    floating = load_description(path, log=lambda notice: None).spec.compile()
    assert floating.nq == 7 + 1 and floating.joint('floating_base_joint').type == 0
    fixed = load_description(path, base='fixed', log=lambda notice: None).spec.compile()
    assert fixed.nq == 1
    sim = Simulation(load_scene(path, {'robot.base': 'fixed', 'rft.plates_per_body': 50}))
    assert sim.settle_steps == 0 and sim.scene.spawn == 'auto'
    assert not [n for n in sim.notices if n.startswith('robot.spawn')]  # (nothing asked)
    sim.step(10)


def test_joints_outside_their_range_start_at_its_nearest_end(tmp_path):
    """A URDF whose zero pose lies outside a knee's range (Unitree's Aliengo: calf range
    -2.78 .. -0.65 rad): the joint starts at -0.65, said at start-up, and its servo holds it
    there instead of fighting the limit."""
    path = tmp_path / 'knee.urdf'
    path.write_text(WORLD_FLOATING.replace('lower="-1" upper="1"', 'lower="-2.7" upper="-0.6"'))
    sim = Simulation(load_scene(path, {'rft.plates_per_body': 50, 'robot.spawn': 'model'}))
    [notice] = [n for n in sim.notices if 'outside' in n]
    assert notice.startswith('joint hinge started outside its range (hinge at 0, range -2.7 ..')
    hinge = sim.model.jnt_qposadr[sim.model.joint('hinge').id]
    assert sim.data.qpos[hinge] == -0.6
    assert sim.commands.sample(0.0).positions[0] == -0.6
    sim.reset()
    assert sim.data.qpos[hinge] == -0.6 and len(sim.notices) == len(set(sim.notices))


def test_a_mimic_joint_follows_its_joint_and_takes_no_commands(tmp_path):
    """A URDF <mimic> (MuJoCo's importer makes it a joint equality): the follower gets no
    position or effort interface, as in ros2_control, and follows the joint it mimics;
    commanded with a servo of its own, the two fought the equality."""
    mimic = WORLD_FLOATING.replace('</robot>', """
  <joint name="twin" type="revolute"><parent link="base"/><child link="leg2"/>
    <origin xyz="0 0.1 -0.1"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="5" velocity="5"/><mimic joint="hinge" multiplier="-1"/>
  </joint>
  <link name="leg2"><inertial><mass value="0.2"/><inertia ixx="0.001" iyy="0.001"
    izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><geometry><sphere radius="0.03"/></geometry></collision></link>
</robot>""")
    path = tmp_path / 'mimic.urdf'
    path.write_text(mimic)
    sim = Simulation(load_scene(path, {'rft.plates_per_body': 50, 'robot.spawn': 'model',
                                       'sand.surface_height': -1.0}))  # (in the air)
    assert sim.servo_joint_names == ('hinge',) and sim.joint_names == ('hinge', 'twin')
    assert sim.commands.set_positions([0.4], now=sim.time).accepted
    sim.model.opt.gravity[:] = 0.0
    sim.step(2000)
    hinge, twin = (sim.data.qpos[sim.model.jnt_qposadr[sim.model.joint(n).id]]
                   for n in ('hinge', 'twin'))
    assert hinge == pytest.approx(0.4, abs=0.01) and twin == pytest.approx(-hinge, abs=0.01)


def test_an_mjcf_without_names_runs_its_bodies_called_by_id(tmp_path):
    """MuJoCo's own examples leave bodies and joints unnamed (slider_crank.xml, cards.xml):
    bodies get body<id> (sand bodies and legs name them), an unnamed joint no interfaces
    (no command could name it), each said at start-up; a fixed base starts where it is
    (spawn auto)."""
    path = tmp_path / 'anon.xml'
    path.write_text('''<mujoco><worldbody>
      <body pos="0 0 0.3"><joint type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03"/>
        <body name="body3" pos="0 0 -0.3"/>
        <body pos="0.1 0 -0.3"><geom type="sphere" size="0.03"/></body>
      </body></worldbody></mujoco>''')
    sim = Simulation(load_scene(path, {'rft.plates_per_body': 50}))
    assert [sim.model.body(b).name for b in range(1, 4)] == ['body1', 'body3', 'body3_']
    assert sim.sand_bodies == ('body1', 'body3_') and sim.base_body == 'body1'
    assert sim.joint_names == () and sim.servo_joint_names == ()
    said = '\n'.join(sim.notices)
    assert '2 bodies without a name, called by their id: body1, body3_' in said
    assert '1 hinge or slide joint(s) without a name: no command interfaces' in said
    assert sim.settle_steps == 0
    sim.step(10)


def test_a_root_fixed_to_a_world_link_stays_welded_unless_the_base_is_set(tmp_path):
    """An arm's URDF mounts its base on a `world` link by a fixed joint: by default (base
    None: as the URDF says) it stays welded there, `floating` frees it; a URDF without a
    world link floats by default (the sandbot)."""
    arm = WORLD_FLOATING.replace('type="floating"', 'type="fixed"')
    path = tmp_path / 'arm.urdf'
    path.write_text(arm)
    assert load_description(path, log=lambda notice: None).spec.compile().nq == 1
    assert load_description(path, base='floating',
                            log=lambda notice: None).spec.compile().nq == 7 + 1
    sim = Simulation(load_scene(path, {'rft.plates_per_body': 50}))
    assert sim.model.nq == 1 and sim.settle_steps == 0
    sandbot = load_description(XACRO, package_paths=PATHS, log=lambda notice: None)
    assert sandbot.spec.compile().joint(FLOATING_JOINT).type == mujoco.mjtJoint.mjJNT_FREE


def test_xacro_args_are_passed():
    description = load_description(XACRO, package_paths=PATHS, xacro_args={'hip_effort': 30},
                                   log=lambda notice: None)
    assert description.effort_limits['fl_hip'] == 30.0
    assert description.effort_limits['fl_knee'] == 12.0


def test_package_found_through_ros_package_path(monkeypatch, tmp_path):
    monkeypatch.setenv('ROS_PACKAGE_PATH', str(PACKAGE.parent))
    description = load_description(XACRO, log=lambda notice: None)
    assert description.spec.compile().nu == 0


def test_package_folder_named_otherwise_found_by_its_manifest(monkeypatch, tmp_path):
    shutil.copytree(PACKAGE, tmp_path / 'src' / 'renamed_folder')
    monkeypatch.setenv('ROS_PACKAGE_PATH', str(tmp_path / 'src'))
    assert PackageResolver().find('sandbot_description') == (tmp_path / 'src' / 'renamed_folder')


def test_unresolvable_package_is_one_clear_error(monkeypatch):
    monkeypatch.delenv('ROS_PACKAGE_PATH', raising=False)
    with pytest.raises(DescriptionError, match=r"sandbot_description.*--package-path"):
        load_description(XACRO)


def test_robot_description_string_loads_like_the_file():
    text = expand_xacro(XACRO, PackageResolver(PATHS))
    description = load_description(text, package_paths=PATHS, log=lambda notice: None)
    assert description.source_path is None
    assert description.initial_positions['rr_knee'] == -0.8
    assert description.spec.compile().nbody == 15


def test_mjcf_loads_as_written():
    description = load_description(Path(__file__).parent / 'scenes' / 'servo_rig.xml')
    assert description.kind == 'mjcf' and description.notices == []
    assert description.spec.compile().nu > 0


def test_urdf_saved_as_xml_is_told_by_its_root_element(tmp_path):
    text = expand_xacro(XACRO, PackageResolver(PATHS))
    (tmp_path / 'robot.xml').write_text(text)
    description = load_description(tmp_path / 'robot.xml', package_paths=PATHS,
                                   log=lambda notice: None)
    assert description.kind == 'urdf'


@pytest.mark.parametrize('text, message', [
    ('<robot name="r"><link name="a"></robot>', r'line 1, column \d+: mismatched tag'),
    ('<sdf version="1.9"/>', r'neither <robot> \(URDF\) nor <mujoco>'),
    ('<robot name="r"><link name="a"/><link name="b"/></robot>', r'one root link'),
    ('<robot name="r"><link name="a"><collision><geometry><mesh filename="nowhere.stl"/>'
     '</geometry></collision></link></robot>', r'collision mesh nowhere.stl not found'),
    ('<robot name="r"><link name="a"/><joint name="j" type="revolute"><parent link="a"/>'
     '<child link="b"/><limit effort="x"/></joint><link name="b"/></robot>',
     r'joint j: limit effort=.x. is not a number'),
])
def test_bad_descriptions_are_refused_with_the_reason(text, message):
    with pytest.raises(DescriptionError, match=message):
        load_description(text)


def test_malformed_urdf_file_names_file_and_line(tmp_path):
    path = tmp_path / 'bad.urdf'
    path.write_text('<robot name="r">\n  <link name="a">\n</robot>\n')
    with pytest.raises(DescriptionError, match=r'bad.urdf: malformed XML at line 3'):
        load_description(path)


def test_unconvertible_collision_mesh_is_refused_naming_the_file(tmp_path):
    (tmp_path / 'broken.dae').write_text('not collada')
    text = ('<robot name="r"><link name="a"><inertial><mass value="1"/><inertia ixx="1" '
            'iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial><collision><geometry>'
            '<mesh filename="broken.dae"/></geometry></collision></link></robot>')
    (tmp_path / 'r.urdf').write_text(text)
    with pytest.raises(DescriptionError, match=r'broken.dae'):
        load_description(tmp_path / 'r.urdf')


def test_xacro_error_and_missing_file_are_one_line(tmp_path):
    (tmp_path / 'bad.urdf.xacro').write_text(
        '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">'
        '<link name="${undefined_property}"/></robot>')
    with pytest.raises(DescriptionError, match=r'bad.urdf.xacro: xacro: .*undefined_property'):
        load_description(tmp_path / 'bad.urdf.xacro')
    with pytest.raises(DescriptionError, match='not found'):
        load_description(tmp_path / 'missing.urdf')
    with pytest.raises(DescriptionError, match="base must be 'floating', 'fixed' or None"):
        load_description(XACRO, base='welded')


BODY = ('<inertial><mass value="1"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" '
        'izz="0.01"/></inertial>')


@pytest.mark.parametrize('use', [f'<link name="$(arg part)">{BODY}</link>',
                                 f'<xacro:if value="$(arg part)"><link name="a">{BODY}</link>'
                                 '</xacro:if>'])
def test_an_undefined_xacro_argument_says_how_to_give_it(tmp_path, use):
    """As a ROS 1 launch file passes it (Unitree's aliengo: `$(arg DEBUG)` in xacro:if)."""
    (tmp_path / 'r.urdf.xacro').write_text(
        f'<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">{use}</robot>')
    with pytest.raises(DescriptionError, match=r'undefined xacro argument part: give it with '
                                               r'--xacro-arg part=VALUE'):
        load_description(tmp_path / 'r.urdf.xacro')
    description = load_description(tmp_path / 'r.urdf.xacro', xacro_args={'part': 'true'})
    assert description.kind == 'urdf'


def _link(name, inertia):
    values = ' '.join(f'{k}="{v}"' for k, v in zip(('ixx', 'ixy', 'ixz', 'iyy', 'iyz', 'izz'),
                                                   inertia))
    return (f'<link name="{name}"><inertial><mass value="0.2"/><inertia {values}/></inertial>'
            '<collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>')


def test_inertias_no_rigid_body_has_become_isotropic_with_their_trace():
    """As vendors' URDFs have them (ANYmal C's hatch: every entry 0.001; its cameras:
    A + B < C; Unitree B2's lidar: 1.7e-27 kg m^2): RViz takes them, MuJoCo refuses to
    compile them."""
    links = {'base': (0.02, 0, 0, 0.03, 0, 0.04), 'hatch': (0.001,) * 6,
             'camera': (0.001, 0, 0, 0.001, 0, 0.003),
             'lidar': (1.68e-27, -3.2e-45, 7.68e-44, 1.68e-27, -9.26e-47, 1.68e-27)}
    joints = ''.join(f'<joint name="to_{n}" type="revolute"><parent link="base"/>'
                     f'<child link="{n}"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" '
                     'effort="1" velocity="1"/></joint>' for n in ('hatch', 'camera', 'lidar'))
    text = (f'<robot name="r">{"".join(_link(n, i) for n, i in links.items())}{joints}'
            '</robot>')
    logged = []
    model = load_description(text, log=logged.append).spec.compile()
    [notice] = [n for n in logged if 'inertia' in n]
    assert 'links hatch, camera, lidar:' in notice
    # a placeholder's (Unitree's B2 lidar link), far below the least MuJoCo takes
    assert model.body('lidar').inertia == pytest.approx([1e-12] * 3, rel=1e-9)
    assert model.body('hatch').inertia == pytest.approx([0.001] * 3)   # trace 0.003 / 3
    assert model.body('camera').inertia == pytest.approx([0.005 / 3] * 3)
    assert sorted(model.body('base').inertia) == pytest.approx([0.02, 0.03, 0.04])
