"""An own robot in sand: a vendor-style MJCF quadruped with torque motors, a keyframe and
dense visual meshes (test/robot_files.py). It loads, its sand bodies and legs are found from
the kinematic tree, the plate count asked is the count made, it stands in sand under the PD
position interface, and it moves under position and effort commands."""
import json
from pathlib import Path
import time

import mujoco
import numpy as np
import pytest
import trimesh

from robot_files import HOME_THIGH, write_torque_quadruped
from rft_sim_ros.cli import main
from rft_sim_ros.control.commands import TrajectoryCommand, TrajectoryPoint
from rft_sim_ros.sand import geoms
from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.sim.runner import run_scene
from rft_sim_ros.sim.simulation import Simulation

CALVES = ('FL_calf', 'FR_calf', 'RL_calf', 'RR_calf')


@pytest.fixture(scope='module')
def robot(tmp_path_factory):
    folder = tmp_path_factory.mktemp('quadruped')
    path, triangles = write_torque_quadruped(folder)  # trunk visual: 327,680 triangles
    assert triangles > 200_000
    return path


def scene(tmp_path, robot_file, **sections):
    """A scene file for the quadruped: `sections` = YAML text per top-level key."""
    text = f'name: quadruped\nmodel: {robot_file}\n' + ''.join(
        f'{key}: {value}\n' for key, value in sections.items())
    path = tmp_path / 'scene.yaml'
    path.write_text(text)
    return load_scene(path)


def test_auto_picks_the_lowest_body_of_each_leg_and_names_legs_by_branch(tmp_path, robot):
    sim = Simulation(scene(tmp_path, robot, rft='{plates_per_body: 100}',
                           robot='{keyframe: home}'))
    assert sim.sand_bodies == CALVES
    # each leg ends at its sand body (its point); the other bodies of its branch come before
    assert {leg: bodies[-1] for leg, bodies in sim.legs.items()} == {
        'FL_hip': 'FL_calf', 'FR_hip': 'FR_calf', 'RL_hip': 'RL_calf', 'RR_hip': 'RR_calf'}
    assert sim.legs['FL_hip'][:-1] == ('FL_hip', 'FL_thigh') and 'trunk' in sim.other_bodies
    assert sim.notices[0] == 'sand bodies (auto): FL_calf, FR_calf, RL_calf, RR_calf'
    # a robot sitting on its trunk: the trunk is the lowest body of its own branch and the
    # legs, folded up, are not within the tolerance: auto picks the trunk alone
    folded = Simulation(scene(tmp_path, robot, rft='{plates_per_body: 100}',
                              robot='{initial_positions: {FL_thigh_joint: -1.5, '
                                    'FR_thigh_joint: -1.5, RL_thigh_joint: -1.5, '
                                    'RR_thigh_joint: -1.5}}'))
    assert 'trunk' in folded.sand_bodies


def test_the_models_home_keyframe_is_the_initial_pose_unless_the_scene_names_one(tmp_path,
                                                                                 robot):
    """Vendors name their standing pose `home` (Unitree's Go2 stood up from it, and fell
    over backwards from its zero pose): it is the default, said at start-up; '' is none."""
    sim = Simulation(scene(tmp_path, robot, rft='{plates_per_body: 50}',
                           robot='{spawn: model}'))
    assert sim.notices[0].startswith("initial pose: the model's keyframe 'home'")
    thigh = sim.model.jnt_qposadr[sim.model.joint('FL_thigh_joint').id]
    assert sim.data.qpos[thigh] == HOME_THIGH
    bare = Simulation(scene(tmp_path, robot, rft='{plates_per_body: 50}',
                            robot="{keyframe: '', spawn: model}"))
    assert bare.data.qpos[thigh] == bare.model.qpos0[thigh] != HOME_THIGH
    assert not [n for n in bare.notices if 'initial pose' in n]


def test_globs_choose_bodies_and_legs_follow_the_tree(tmp_path, robot):
    sim = Simulation(scene(tmp_path, robot, rft="{sand_bodies: ['*_thigh', '*_calf'], "
                                                "plates_per_body: 100}"))
    assert set(sim.sand_bodies) == {f'{leg}_{part}' for leg in ('FL', 'FR', 'RL', 'RR')
                                    for part in ('thigh', 'calf')}
    # base outwards: calf = foot point
    assert [b for b in sim.legs['FL_hip'] if b in sim.sand_bodies] == ['FL_thigh', 'FL_calf']
    with pytest.raises(SceneError, match=r"rft.sand_bodies: sand body '\*foot\*' matches no body"):
        Simulation(scene(tmp_path, robot, rft="{sand_bodies: '*foot*'}"))


def test_plates_come_from_collision_geoms_in_the_count_asked(tmp_path, robot):
    sim = Simulation(scene(tmp_path, robot, rft="{sand_bodies: [trunk, '*_calf'], "
                                                "plates_per_body: 300}"))
    counts = np.diff(sim.engine.plate_start)[:len(sim.sand_bodies)]
    assert np.all(np.abs(counts - 300) <= 6), counts  # +-2 %
    trunk = sim.engine.body_names.index('trunk')
    plates = sim.engine.local_pos[sim.engine.plate_start[trunk]:sim.engine.plate_start[trunk + 1]]
    # on the collision box (half height 5 cm), not the visual ellipsoid (6 cm)
    assert np.max(np.abs(plates[:, 2])) == pytest.approx(0.05, abs=1e-9)


def test_a_body_with_only_a_dense_visual_mesh_is_simplified_to_the_count(tmp_path,
                                                                         monkeypatch):
    shell = trimesh.creation.icosphere(subdivisions=6, radius=1.0)  # 81,920 triangles
    shell.apply_scale((0.05, 0.03, 0.02))
    shell.export(tmp_path / 'pebble.obj')
    (tmp_path / 'pebble.xml').write_text(
        '<mujoco><asset><mesh name="pebble" file="pebble.obj"/></asset><worldbody>'
        '<body name="pebble" pos="0 0 0.05"><freejoint/>'
        '<geom type="mesh" mesh="pebble" contype="0" conaffinity="0" mass="0.2"/>'
        '</body></worldbody></mujoco>')
    (tmp_path / 'scene.yaml').write_text(
        'model: pebble.xml\nrft: {sand_bodies: [pebble], plates_per_body: 500}\n')
    sim = Simulation(load_scene(tmp_path / 'scene.yaml'))
    assert abs(sim.engine.plates_total - 500) <= 10
    assert sim.engine.areas.sum() == pytest.approx(shell.area, rel=0.03)
    assert len(list(geoms.plate_cache_dir().glob('*.npz'))) > 0
    monkeypatch.setattr(geoms, '_make_plates', None)  # plates must now come from the cache
    again = Simulation(load_scene(tmp_path / 'scene.yaml'))
    np.testing.assert_array_equal(again.engine.local_pos, sim.engine.local_pos)
    other = load_scene(tmp_path / 'scene.yaml', {'rft.plates_per_body': 400})
    with pytest.raises(TypeError):  # another count is another key: not in the cache
        Simulation(other)


def test_default_gains_follow_the_mass_and_servos_override_them_by_pattern(tmp_path, robot):
    sim = Simulation(scene(tmp_path, robot, rft='{plates_per_body: 50}',
                           robot='{keyframe: home}',
                           servos="{'*_calf_joint': {kp: 80, kd: 2}, 'RR_*': {effort: 10}}"))
    gains = sim.interfaces.gains
    assert (gains['FL_calf_joint'].kp, gains['FL_calf_joint'].kd) == (80, 2)
    assert gains['RR_calf_joint'].effort == 10 and gains['FL_calf_joint'].effort == 33.5
    # thigh: 15 kg x g x reach / 0.05 rad; its reach in the home pose: the foot, 0.279 m below
    reach = gains['FL_thigh_joint'].kp * 0.05 / (15.0 * 9.81)
    assert reach == pytest.approx(0.2 * 2 * np.cos(HOME_THIGH), abs=1e-3)
    pd = sim.model.actuator('pd_FL_thigh_joint').id
    assert sim.model.actuator_forcerange[pd, 1] == 33.5  # the motor's ctrlrange
    assert sim.model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST


def _standing(tmp_path, robot, duration_steps):
    sim = Simulation(scene(tmp_path, robot, rft='{plates_per_body: 300}',
                           robot='{keyframe: home, spawn: rest}'))
    trunk = sim.model.body('trunk').id
    samples = []
    for _ in range(duration_steps // 50):
        sim.step(50)
        samples.append((sim.time, *sim.data.xpos[trunk], np.linalg.norm(sim.data.qvel[:3])))
    return sim, np.array(samples)


def test_a_torque_motor_robot_stands_in_sand_from_its_keyframe(tmp_path, robot):
    """Under the PD position interface, from `home`, 10 s: over the last 5 s the base moves
    slower than 1 mm/s and drifts less than 1 mm."""
    sim, s = _standing(tmp_path, robot, 10_000)
    last = s[s[:, 0] >= 5.0]
    assert last[:, 4].max() < 1e-3
    assert np.linalg.norm(last[-1, 1:4] - last[0, 1:4]) < 1e-3
    # it stands on its feet, in the sand: the feet carry the weight
    assert sim.engine.body_wrenches[:, 2].sum() == pytest.approx(15.0 * 9.81, rel=0.02)
    joints = sim.data.qpos[sim.model.jnt_qposadr[sim.model.joint('FL_thigh_joint').id]]
    assert joints == pytest.approx(HOME_THIGH, abs=0.05)


def test_it_moves_under_position_and_effort_commands(tmp_path, robot):
    sim, s = _standing(tmp_path, robot, 500)
    trunk = sim.model.body('trunk').id
    standing = sim.data.xpos[trunk, 2]
    # position: crouch (thigh 0.8 -> 1.0, calf -1.6 -> -2.0): feet 0.279 -> 0.216 m below
    # the hips, so the base lowers by ~6.3 cm
    crouch = [0.0, 1.0, -2.0] * 4
    assert sim.commands.set_positions(crouch, now=sim.time).accepted
    sim.step(1500)
    assert standing - sim.data.xpos[trunk, 2] == pytest.approx(0.063, abs=0.01)
    # effort: the torques the PD holds the crouch with, applied as efforts, keep it there ...
    holding = sim.data.actuator_force[sim.interfaces.position_actuators].copy()
    crouched = sim.data.xpos[trunk, 2]
    assert sim.commands.set_efforts(holding, now=sim.time).accepted
    sim.step(300)
    assert sim.interfaces.mode == 'effort'
    assert abs(sim.data.xpos[trunk, 2] - crouched) < 0.01
    # ... and zero efforts let it fold (the PD is off in effort mode)
    sim.commands.set_efforts(np.zeros(12), now=sim.time)
    sim.step(150)
    assert crouched - sim.data.xpos[trunk, 2] > 0.03
    # a trajectory takes over again from where the joints are and brings it back up into
    # the crouch within 1 s
    back = TrajectoryCommand(sim.servo_joint_names, [TrajectoryPoint(crouch, 1.0)])
    assert sim.commands.set_trajectory(back, now=sim.time).accepted
    sim.step(1500)
    assert sim.interfaces.mode == 'position'
    assert sim.data.xpos[trunk, 2] == pytest.approx(crouched, abs=0.01)
    assert not sim.commands.set_efforts([1.0] * 11, now=sim.time).accepted  # one short


@pytest.mark.slow
def test_startup_of_a_dense_quadruped_is_under_3_s_warm(tmp_path, capsys):
    """Speed target (issue 12): a 12-DOF quadruped whose visual meshes total more than
    500,000 triangles starts in under 3 s once warm (compiled kernels and plate cache)."""
    path, triangles = write_torque_quadruped(tmp_path, thigh_subdivisions=6)
    assert triangles > 500_000
    text = f'model: {path}\nrft: {{plates_per_body: 300}}\nrobot: {{keyframe: home}}\n'
    (tmp_path / 'scene.yaml').write_text(text)
    times = []
    for _ in range(3):
        started = time.perf_counter()
        sim = Simulation(load_scene(tmp_path / 'scene.yaml'))
        times.append(time.perf_counter() - started)
    with capsys.disabled():
        print(f'\nstart-up of {triangles} visual triangles, 4 x 300 plates: first '
              f'{times[0]:.2f} s, warm {min(times[1:]):.2f} s; plates made '
              f'{list(np.diff(sim.engine.plate_start))}')
    assert min(times[1:]) < 3.0


def test_rft_sim_run_takes_the_robot_file_with_keyframe_and_spawn(robot, tmp_path, capsys):
    """The one-line job: the quadruped from its file, `auto` sand bodies printed at start-up,
    dropped 2 cm onto the sand from its keyframe; the external scenario reports the generic
    metrics."""
    out = tmp_path / 'run'
    assert main(['run', str(robot), '--keyframe', 'home', '--spawn', 'drop:0.02',
                 '--plates-per-body', '100', '--duration', '0.3', '--no-bag',
                 '--out', str(out)]) == 0
    err = capsys.readouterr().err
    assert 'rft-sim: sand bodies (auto): FL_calf, FR_calf, RL_calf, RR_calf' in err
    summary = json.loads((out / 'summary.json').read_text())
    generic = summary['generic_metrics']
    assert {leg: bodies[-1] for leg, bodies in summary['legs'].items()} == {
        f'{leg}_hip': f'{leg}_calf' for leg in ('FL', 'FR', 'RL', 'RR')}
    assert generic['stable'] and 0 < generic['max_sinkage_m_FL_calf'] < 0.1
    assert generic['peak_force_z_N_FL_hip'] > 0
    assert main(['run', str(robot), '--spawn', 'hover', '--out', str(tmp_path / 'x')]) == 2
    assert 'robot.spawn: must be auto, model, rest or drop:HEIGHT' in capsys.readouterr().err


def test_a_xacro_urdf_robot_gets_its_limits_initial_values_and_feet(tmp_path):
    """The URDF side (test/robots/sandbot_description): no actuators, so every joint gets a
    PD position interface limited to the URDF <limit effort>; the robot starts in its
    ros2_control initial values and holds them; auto finds its four feet; it rests in sand."""
    package = Path(__file__).parent / 'robots' / 'sandbot_description'
    xacro = package / 'urdf' / 'sandbot.urdf.xacro'
    sim = Simulation(load_scene(xacro, {
        'robot.package_paths': {'sandbot_description': str(package)},
        'robot.xacro_args': {'hip_effort': '20'}, 'robot.spawn': 'rest',
        'rft.plates_per_body': 100}))
    assert sorted(sim.sand_bodies) == ['fl_foot', 'fr_foot', 'rl_foot', 'rr_foot']
    assert sim.interfaces.gains['fl_hip'].effort == 20.0   # the xacro argument's limit
    assert sim.interfaces.gains['fl_knee'].effort == 12.0
    hip = sim.model.jnt_qposadr[sim.model.joint('fl_hip').id]
    assert sim.data.qpos[hip] == pytest.approx(0.4, abs=0.02)  # ros2_control initial_value
    base = sim.model.body(sim.base_body).id
    start = sim.data.xpos[base].copy()
    sim.step(1000)
    assert np.linalg.norm(sim.data.xpos[base] - start) < 2e-3  # settled by spawn rest
    assert sim.data.qpos[hip] == pytest.approx(0.4, abs=0.02)


def test_a_runs_solve_counts_leave_spawn_rests_settling_out(tmp_path):
    """summary.json's implicit counts are the run's: the steps spawn rest took to settle
    (reported as spawn_settle_steps) are not in them, nor in the solves per step."""
    package = Path(__file__).parent / 'robots' / 'sandbot_description'
    scene = load_scene(package / 'urdf' / 'sandbot.urdf.xacro', {
        'robot.package_paths': {'sandbot_description': str(package)},
        'robot.spawn': 'rest', 'rft.plates_per_body': 100})
    summary = run_scene(scene, duration=0.2, progress=False, plots=False)
    fresh = Simulation(scene)
    solves, unsettled = fresh.engine.solves, fresh.engine.unsettled_steps
    assert fresh.settle_steps == summary['spawn_settle_steps'] > 100 and solves > 100
    fresh.step(summary['steps'])
    assert summary['implicit_solves_per_step'] * summary['steps'] == pytest.approx(
        fresh.engine.solves - solves, abs=1e-6)
    assert summary['implicit_unsettled_steps'] == fresh.engine.unsettled_steps - unsettled


FLOORBOT = """
<mujoco model="floorbot">
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <geom name="rock" type="box" pos="3 0 0" size="0.1 0.1 0.1"/>
    <geom name="backdrop" type="plane" pos="0 0 -1" contype="0" conaffinity="0"/>
    <geom name="wall" type="plane" pos="2 0 0" euler="0 -90 0" size="1 1 0.1"/>
    <body name="base" pos="0 0 0.3">
      <freejoint/>
      <geom type="box" size="0.1 0.06 0.02" mass="2"/>
      <body name="leg1" pos="0.08 0 -0.02"><joint name="j1" axis="0 1 0" range="-1 1"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.12" size="0.012" mass="0.1"/></body>
      <body name="leg2" pos="-0.08 0 -0.02"><joint name="j2" axis="0 1 0" range="-1 1"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.12" size="0.012" mass="0.1"/></body>
    </body>
  </worldbody>
</mujoco>"""


def test_a_models_own_floor_plane_gives_way_to_the_sand_unless_kept(tmp_path):
    """A vendor scene's floor plane would hold the robot up at the sand's surface: its
    collisions are switched off (said in a notice), so the legs sink into the sand; other
    world geoms (a rock, a wall) and a plane that touches nothing stay as they are; with
    sand.keep_floor the floor stays rigid and the legs never enter the sand."""
    path = tmp_path / 'floorbot.xml'
    path.write_text(FLOORBOT)
    depths = {}
    for keep in (False, True):
        sim = Simulation(load_scene(path, {'sand.keep_floor': keep, 'robot.spawn': 'drop:0.0'}))
        floor, rock = sim.model.geom('floor').id, sim.model.geom('rock').id
        assert bool(sim.model.geom_contype[floor]) == keep
        assert sim.model.geom_contype[rock] == 1  # an obstacle, not a floor
        assert sim.model.geom('wall').contype[0] == 1  # a plane standing up: a wall
        said = [n for n in sim.notices if n.startswith('floor plane floor: rigid collisions')]
        assert len(said) == (0 if keep else 1) and 'backdrop' not in ' '.join(sim.notices)
        engine, deepest = sim.engine, []
        for _ in range(50):
            sim.step(10)
            deepest.append(max(-(sim.data.xpos[b, 2] + engine.local_pos[
                engine.plate_start[n]:engine.plate_start[n + 1]]
                @ sim.data.xmat[b].reshape(3, 3)[2]).min() for n, b in enumerate(engine.body_ids)))
        depths[keep] = max(deepest)  # of the deepest plate below the sand surface (z 0), m
    assert depths[False] > 0.01  # the feet sink into the sand
    assert depths[True] < 0.003  # held by the floor (MuJoCo's soft contact: a mm or so)


def test_a_models_own_hfield_is_rigid_ground_unless_it_is_the_sands_surface(tmp_path):
    """A terrain generator's hfield in the scene (unnamed geom, named asset) stays rigid
    ground under a plane of sand, and a notice says so with the keys that make it the sand's
    surface; given those keys it is the surface, its collisions off, and no notice."""
    hfield = ('<asset><hfield name="park" nrow="2" ncol="2" size="2 2 0.1 0.1"/></asset>'
              '<worldbody><geom type="hfield" hfield="park" pos="0 0 -0.05"/>')
    path = tmp_path / 'parkbot.xml'
    path.write_text(FLOORBOT.replace('<worldbody>', hfield, 1))
    for surface in ({}, {'sand.surface.type': 'hfield', 'sand.surface.geom': 'park'}):
        sim = Simulation(load_scene(path, surface))
        park = int(np.flatnonzero(sim.model.geom_type == mujoco.mjtGeom.mjGEOM_HFIELD)[0])
        said = [n for n in sim.notices if n.startswith('hfield geom park: rigid ground')]
        if surface:
            assert not said and sim.model.geom_contype[park] == 0
        else:
            assert sim.model.geom_contype[park] == 1
            assert said and said[0].endswith('--set sand.surface.type=hfield '
                                             "--set sand.surface.geom=park makes it the "
                                             "sand's surface")
