"""ROS-style robots in sand: the xacro URDF test robot (test/robots/sandbot_description:
$(find) include, package:// OBJ and COLLADA meshes, a COLLADA visual, <ros2_control> and
<gazebo> tags, a fixed root link) and the bundled quadruped. They load, make the plate count
asked, stand in sand from their ros2_control initial pose, and move under commands."""
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from rft_sim_ros.cli import main
from rft_sim_ros.robot.packages import PackageResolver
from rft_sim_ros.robot.xacro_files import expand_xacro
from rft_sim_ros.ros import messages
from rft_sim_ros.ros.factory import RosbagsFactory
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.scenes.quadruped import leg_forward
from rft_sim_ros.sim.simulation import Simulation

PACKAGE = Path(__file__).parent / 'robots' / 'sandbot_description'
XACRO = PACKAGE / 'urdf' / 'sandbot.urdf.xacro'
FEET = ('fl_foot', 'fr_foot', 'rl_foot', 'rr_foot')
#: sandbot: trunk 3 kg + 4 legs x 0.3 kg
SANDBOT_WEIGHT_N = 4.2 * 9.81


@pytest.fixture(scope='module')
def sandbot():
    """The sandbot as `rft-sim run sandbot.urdf.xacro` loads it (auto sand bodies, spawn
    rest), stood 1 s."""
    scene = load_scene(XACRO, {'robot.package_paths': {'sandbot_description': str(PACKAGE)},
                               'rft.plates_per_body': 200})
    sim = Simulation(scene)
    sim.step(1000)
    return sim


def test_auto_sand_bodies_are_the_feet_with_the_plates_asked(sandbot):
    assert sandbot.sand_bodies == FEET  # mesh feet on fixed joints, one per branch
    counts = np.diff(sandbot.engine.plate_start)[:len(FEET)]
    assert np.all(np.abs(counts - 200) <= 4), counts  # +-2 %


def test_stands_in_sand_from_the_ros2_control_pose(sandbot):
    sim = sandbot
    knees = [sim.data.joint(f'{leg}_knee').qpos[0] for leg in ('fl', 'fr', 'rl', 'rr')]
    assert knees == pytest.approx([-0.8] * 4, abs=0.05)  # ros2_control initial_value
    assert sim.engine.body_wrenches[:, 2].sum() == pytest.approx(SANDBOT_WEIGHT_N, rel=0.03)
    speed = np.linalg.norm(sim.state().base_linear_velocity)
    assert speed < 5e-3


def test_moves_under_position_commands(sandbot):
    sim = sandbot
    trunk = sim.model.body('trunk').id
    before = sim.data.xpos[trunk].copy()
    # straighten the legs (hip 0.4 -> 0.2, knee -0.8 -> -0.4): the trunk rises
    names = list(sim.servo_joint_names)
    targets = [0.2 if name.endswith('hip') else -0.4 for name in names]
    assert sim.commands.set_positions(targets, now=sim.time).accepted
    sim.step(1500)
    hip = sim.data.joint('fl_hip').qpos[0]
    assert hip == pytest.approx(0.2, abs=0.05)
    # feet 0.12 (cos 0.4 + cos 0.4) -> 0.12 (cos 0.2 + cos 0.2) below the hips: + 2.5 cm
    rise = 0.12 * 2 * (np.cos(0.2) - np.cos(0.4))
    assert sim.data.xpos[trunk, 2] - before[2] == pytest.approx(rise, abs=0.008)


@pytest.mark.parametrize('overrides, said', [
    ({'servos': {'*': 'passive'}}, 'collapsed'),  # limp: folds onto its trunk
    ({'zeta': 0.002}, 'sank'),  # 1/2000 of play sand: its legs out, it goes under
])
def test_a_robot_that_cannot_stand_is_said_to_collapse_or_sink_not_upright(overrides, said):
    """Not turned over, yet not standing: limp, the sandbot settles with its centre of mass
    at 9 cm above its feet (23 cm as set down); in sand 2000 times looser than play sand,
    its trunk goes 66 cm under. Spawn rest does not start it from there but from where it
    was set down (saying why), so the run shows it happen, and the outcome names it."""
    scene = load_scene(XACRO, {'robot.package_paths': {'sandbot_description': str(PACKAGE)},
                               'rft.plates_per_body': 100, **overrides})
    sim = Simulation(scene)
    assert any(n.startswith(f'spawn rest: {said}: ') for n in sim.notices), sim.notices
    sim.step(1000)
    outcome = sim.outcome()
    assert outcome[said] and 0.0 < outcome[f'{said}_at_s'] < 0.5 and sim.down
    assert not outcome['fell'] and outcome['max_tilt_deg'] < 5.0
    assert outcome['words'].startswith(f'{said} at t = ')
    assert 'upright' not in outcome['words']


def test_the_bundled_quadruped_trots_forward_in_sand(tmp_path):
    out = tmp_path / 'trot'
    assert main(['run', 'quadruped', '--set', 'settle_time=0.5', '--set', 'cycles=3',
                 '--out', str(out), '--quiet', '--no-bag']) == 0
    summary = json.loads((out / 'summary.json').read_text())
    assert [summary['plates_per_body'][b] for b in summary['sand_bodies']] == [300] * 4
    assert summary['stable'] and not summary['outcome']['fell']
    metrics = summary['generic_metrics']
    forward = metrics['base_displacement_xyz_m'][0]
    # a stance foot moves back 8 cm in 0.6 of a cycle: without slip the body moves at
    # 0.08 m x 1.5 Hz / 0.6 = 0.2 m/s, 0.4 m over the 2 s of 3 cycles, less the 0.5 s ramp
    # (half speed on average): 0.35 m; sand slip keeps it below that, the trot must still
    # carry it more than half way
    assert 0.17 < forward < 0.35
    assert all(0.003 < metrics[f'mean_stance_sinkage_m_{leg}_foot'] < 0.05
               for leg in ('fl', 'fr', 'rl', 'rr'))


def test_quadruped_stands_on_its_feet_at_the_pose_height():
    scene = load_scene('quadruped', {'gait': 'none'})
    sim = Simulation(scene)
    sim.step(1000)
    _, z = leg_forward(0.6, -1.2)
    foot_bottom = sim.data.xpos[sim.model.body('base').id, 2] + z - 0.025
    depth = scene.surface_height - foot_bottom
    assert 0.0 < depth < 0.03  # feet in the sand, carrying 9.8 kg
    assert sim.engine.body_wrenches[:, 2].sum() == pytest.approx(9.8 * 9.81, rel=0.03)


def _root_link(urdf_xml):
    """The URDF's root link: the one that is no joint's child (robot_state_publisher's root)."""
    robot = ET.fromstring(urdf_xml)
    children = {joint.find('child').get('link') for joint in robot.findall('joint')}
    [root] = [link.get('name') for link in robot.findall('link')
              if link.get('name') not in children]
    return root


def test_odom_and_tf_name_the_base_frame_as_the_urdf_root_link(sandbot):
    """odom -> <root link> joins the tree robot_state_publisher publishes from the same
    description (root link 'base', not 'base_link', in both robots)."""
    urdf = expand_xacro(XACRO, PackageResolver({'sandbot_description': str(PACKAGE)}))
    quadruped = Simulation(load_scene('quadruped', {'rft.plates_per_body': 50}))
    for sim, root in ((sandbot, _root_link(urdf)), (quadruped, 'base')):
        state = sim.state()
        assert state.base_frame == root == 'base'
        factory = RosbagsFactory()
        assert messages.odometry_message(factory, state).child_frame_id == root
        assert messages.tf_message(factory, state).transforms[0].child_frame_id == root
