"""sim/outcome.py: the lowest point of each geom type (a mesh's too), exact against a dense
sampling of its surface; the tilt, fall time and deepest point a watch records, the tilt from
the pose as set down, a collapse and a sinking, bodies without collision geoms; the words."""
import mujoco
import numpy as np
import pytest

from rft_sim_ros.sand.geoms import geom_mesh
from rft_sim_ros.sand.surface import Plane
from rft_sim_ros.sim.outcome import LowestPoints, OutcomeWatch, words

SHAPES = """<mujoco><asset><mesh name="wedge" vertex="0 0 0  0.2 0 0  0 0.1 0  0 0 0.05"/></asset>
<worldbody><body name="b" pos="0.1 -0.2 0.5" euler="0.7 -0.4 1.1"><freejoint/>
  <geom type="sphere" size="0.05" pos="0.1 0 0"/>
  <geom type="capsule" size="0.03 0.1" pos="0 0.1 0" euler="0.3 0.2 0"/>
  <geom type="cylinder" size="0.04 0.06" pos="0 0 0.1" euler="-0.5 0.1 0.2"/>
  <geom type="ellipsoid" size="0.05 0.02 0.08" pos="-0.1 0 0" euler="0.2 0.9 0"/>
  <geom type="box" size="0.05 0.03 0.02" pos="0 -0.1 0" euler="0.4 0.4 0.4"/>
  <geom type="mesh" mesh="wedge" pos="0 0 -0.1"/>
</body></worldbody></mujoco>"""


def test_the_lowest_point_of_each_geom_is_exact():
    model = mujoco.MjModel.from_xml_string(SHAPES)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    points = LowestPoints(model, range(model.ngeom))(data)
    for g in range(model.ngeom):
        surface = np.asarray(geom_mesh(model, g, 0.002).vertices)  # fine, on the surface
        world = data.geom_xpos[g] + surface @ data.geom_xmat[g].reshape(3, 3).T
        lowest = world[np.argmin(world[:, 2])]
        assert points[g, 2] == pytest.approx(lowest[2], abs=2e-5)
        np.testing.assert_allclose(points[g], lowest, atol=0.01)  # (a flat face: any)


FALLER = """<mujoco><worldbody><body name="base" pos="0 0 0.05"><freejoint/>
  <geom type="box" size="0.1 0.1 0.05" mass="1"/>
  <body name="arm" pos="0.2 0 0"><joint axis="0 1 0"/>
  <geom type="sphere" size="0.02" mass="0.1"/></body></body></worldbody></mujoco>"""


def test_a_watch_records_the_tilt_the_fall_and_the_deepest_point():
    model = mujoco.MjModel.from_xml_string(FALLER)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    base = model.body('base').id
    watch = OutcomeWatch(model, base, plated=[base])
    watch.set_down(data)
    watch.start()
    sand = Plane(0.0)
    for time, angle, z in ((1.1, 30.0, 0.05), (1.2, 60.0, -0.03), (1.3, 90.0, 0.2)):
        half = np.radians(angle) / 2
        data.qpos[2], data.qpos[3:7] = z, (np.cos(half), np.sin(half), 0.0, 0.0)
        mujoco.mj_forward(model, data)
        watch.observe(data, sand, time)
    outcome = watch.result(data, sand, steps=100, unsettled=25, handed_back=5)
    assert outcome['fell'] and outcome['fell_at_s'] == 1.2
    assert outcome['max_tilt_deg'] == pytest.approx(90.0)
    assert outcome['final_tilt_deg'] == pytest.approx(90.0)
    # at 60 deg, 3 cm down: the box's lowest corner, 0.1 sin 60 + 0.05 cos 60 below its centre
    deepest = outcome['deepest']
    assert deepest['body'] == 'base' and deepest['has_plates'] and deepest['time_s'] == 1.2
    assert deepest['sinkage_m'] == pytest.approx(0.03 + 0.1 * np.sin(np.pi / 3) + 0.025)
    assert outcome['max_uncovered_sinkage_m'] == pytest.approx(0.03 + 0.02)  # the arm
    assert outcome['unsettled_step_share'] == 0.25
    assert outcome['rows_handed_back_step_share'] == 0.05
    assert outcome['words'].startswith('fell at t = 1.20 s: base turned 90 deg; lying on the')
    assert ('in 25 % of steps the implicit solve froze plates whose leading/trailing sets '
            'cycled') in outcome['words']
    assert "in 5 % of steps MuJoCo's own solver took the constraint rows" in outcome['words']


def _turn(model, data, angle_deg, z):
    half = np.radians(angle_deg) / 2
    data.qpos[2], data.qpos[3:7] = z, (np.cos(half), np.sin(half), 0.0, 0.0)
    mujoco.mj_forward(model, data)


def test_the_tilt_counts_from_the_pose_as_set_down_not_from_the_start():
    """A robot set down upright that settles leaning 34 deg (spawn rest, before the clock
    starts) has turned 34 deg, not 0: the tilt is measured from how it was set down."""
    model = mujoco.MjModel.from_xml_string(FALLER)
    data = mujoco.MjData(model)
    _turn(model, data, 0.0, 0.05)
    watch = OutcomeWatch(model, model.body('base').id, plated=[])
    watch.set_down(data)
    _turn(model, data, 34.0, 0.05)  # (settled)
    watch.start()
    watch.observe(data, Plane(0.0), 0.04)
    outcome = watch.result(data, Plane(0.0), steps=1, unsettled=0)
    assert outcome['max_tilt_deg'] == pytest.approx(34.0)
    assert not outcome['fell']
    assert outcome['words'].startswith('upright: base turned at most 34 deg')


#: A base box (1 kg) on one slide-jointed leg, its foot a sphere (0.1 kg, r 2 cm): the leg
#: slides up into the base as the robot folds; a `tail` without geoms hangs behind.
LEGGED = """<mujoco><worldbody><body name="base" pos="0 0 0.42"><freejoint/>
  <geom type="box" size="0.1 0.1 0.05" mass="1"/>
  <body name="foot" pos="0 0 -0.4"><joint name="leg" type="slide" axis="0 0 1"/>
    <geom type="sphere" size="0.02" mass="0.1"/></body>
  <body name="tail" pos="-0.3 0 0"><joint axis="0 1 0"/><inertial pos="0 0 0" mass="0.01"
    diaginertia="1e-6 1e-6 1e-6"/></body></body></worldbody></mujoco>"""


def _stand(model, data, base_z, foot_depth=0.0):
    """The base at base_z (m), upright, the foot's lowest point foot_depth below z = 0."""
    data.qpos[2], data.qpos[3:7] = base_z, (1.0, 0.0, 0.0, 0.0)
    data.joint('leg').qpos[0] = 0.42 - base_z - foot_depth  # foot centre at 0.02 - depth
    mujoco.mj_forward(model, data)


def _legged_watch():
    """LEGGED set down standing (its foot's lowest point on the sand), and its watch."""
    model = mujoco.MjModel.from_xml_string(LEGGED)
    data = mujoco.MjData(model)
    base, foot = model.body('base').id, model.body('foot').id
    watch = OutcomeWatch(model, base, plated=[base, foot], feet=[foot])
    _stand(model, data, 0.42)
    watch.set_down(data)
    watch.start()
    return model, data, watch


def test_a_watch_says_when_the_robot_collapsed_and_when_it_sank():
    """Stance height: the centre of mass above the foot's lowest point. Set down at 0.384 m
    (base and tail 1.01 kg at 0.42, the foot 0.1 kg at 0.02, over 1.11 kg); at 0.274 m it
    stands, at 0.0928 m (below half) it collapsed; lowered 0.2 m into the sand, its base 15
    cm deep, it sank."""
    model, data, watch = _legged_watch()
    sand = Plane(0.0)
    for time, base_z, foot_depth in ((1.1, 0.3, 0.0), (1.2, 0.1, 0.0), (1.3, -0.1, 0.2)):
        _stand(model, data, base_z, foot_depth)
        watch.observe(data, sand, time)
    outcome = watch.result(data, sand, steps=1, unsettled=0)
    assert outcome['stance_height_set_down_m'] == pytest.approx((1.01 * 0.42 + 0.002) / 1.11)
    assert outcome['min_stance_height_m'] == pytest.approx((1.01 * 0.1 + 0.002) / 1.11)
    assert outcome['collapsed'] and outcome['collapsed_at_s'] == 1.2
    assert outcome['sank'] and outcome['sank_at_s'] == 1.3
    assert outcome['max_base_depth_m'] == pytest.approx(0.15)
    assert not outcome['fell'] and watch.down
    assert outcome['words'].startswith(
        'sank at t = 1.30 s: its base went 15 cm into the sand; collapsed at t = 1.20 s: its '
        'centre of mass came down to 9.28 cm above its sand bodies, from 38.4 cm as set '
        'down; base turned at most 0 deg; foot ends 20 cm below the sand surface')
    assert watch.problem(data, sand).startswith('collapsed: its centre of mass 9.28 cm above')
    _stand(model, data, -0.1, 0.52)  # its leg out, 52 cm down: the base 15 cm in
    assert watch.problem(data, sand) == 'sank: its base 15 cm into the sand'


def test_a_robot_that_keeps_its_stance_has_not_collapsed_however_deep_its_feet_sink():
    """Feet 10 cm into the sand (the hexapod's dactyls), the base above it: neither."""
    model, data, watch = _legged_watch()
    _stand(model, data, 0.32, 0.1)
    watch.observe(data, Plane(0.0), 0.5)
    outcome = watch.result(data, Plane(0.0), steps=1, unsettled=0)
    assert not (outcome['collapsed'] or outcome['sank'] or watch.down)
    assert watch.problem(data, Plane(0.0)) is None
    assert outcome['words'].startswith('upright: base turned at most 0 deg; deepest: foot 10 cm')


def test_without_sand_bodies_or_joints_the_stance_is_not_watched():
    """A rigid body (a plate pressed into the sand) or a robot without sand bodies: no
    collapse or sinking is judged, their fields null."""
    model = mujoco.MjModel.from_xml_string(LEGGED)
    data = mujoco.MjData(model)
    _stand(model, data, 0.1)
    watch = OutcomeWatch(model, model.body('base').id, plated=[], feet=[])
    watch.set_down(data)
    watch.start()
    _stand(model, data, -0.3, 0.4)
    watch.observe(data, Plane(0.0), 0.1)
    outcome = watch.result(data, Plane(0.0), steps=1, unsettled=0)
    assert outcome['stance_height_set_down_m'] is None and outcome['max_base_depth_m'] is None
    assert not (outcome['collapsed'] or outcome['sank'])
    rigid = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body name="plate"><freejoint/><geom type="box" '
        'size="0.05 0.05 0.005"/></body></worldbody></mujoco>')
    plate = rigid.body('plate').id
    assert OutcomeWatch(rigid, plate, plated=[plate], feet=[plate])._watch_body is False


def test_a_body_without_collision_geoms_is_watched_by_its_origin():
    """`tail` has no geom: nothing collides it with the sand, so its origin is watched, and
    where it is the deepest point the words say it passed through."""
    model, data, watch = _legged_watch()
    data.qpos[3:7] = (np.cos(np.pi / 8), 0.0, -np.sin(np.pi / 8), 0.0)  # tail down 45 deg
    data.qpos[2] = 0.1
    data.joint('leg').qpos[0] = 0.38  # (the foot drawn up to the base)
    mujoco.mj_forward(model, data)
    tail = data.xpos[model.body('tail').id]
    watch.observe(data, Plane(0.0), 0.2)
    outcome = watch.result(data, Plane(0.0), steps=1, unsettled=0)
    deepest = outcome['deepest']
    assert deepest['body'] == 'tail' and not deepest['has_plates']
    assert deepest['sinkage_m'] == pytest.approx(-tail[2])
    assert '(no plates: it passed through)' in outcome['words']


def test_a_fallen_robot_still_moving_is_not_lying():
    """Tumbling down a slope at 3.1 m/s at the end: not 'lying on the sand'."""
    tumbling = {'fell': True, 'fell_at_s': 1.08, 'max_tilt_deg': 176.0,
                'unsettled_step_share': 0.0, 'final_base_speed_mps': 3.1,
                'deepest': None, 'max_uncovered_sinkage_m': None}
    assert words(tumbling, 0.0, 'base').startswith(
        'fell at t = 1.08 s: base turned 176 deg; still moving at 3.1 m/s at the end')
    assert words(dict(tumbling, final_base_speed_mps=0.01), 0.0, 'base').startswith(
        'fell at t = 1.08 s: base turned 176 deg; lying on the sand')


def test_the_words_say_a_body_left_under_the_sand():
    outcome = {'fell': True, 'fell_at_s': 0.8, 'max_tilt_deg': 95.0, 'unsettled_step_share': 0,
               'deepest': {'body': 'pelvis', 'sinkage_m': 1.2, 'time_s': 1.5,
                           'has_plates': False},
               'max_uncovered_sinkage_m': 1.2}
    assert words(outcome, 0.9, 'pelvis') == (
        'fell at t = 0.80 s: base turned 95 deg; pelvis ends 90 cm below the sand surface; '
        'deepest: pelvis 1.2 m below the surface at t = 1.50 s (no plates: it passed through)')


def test_the_words_say_no_body_reached_the_sand():
    """A run that ends before the robot touches the sand (a short drop, a robot held above
    it) says so, rather than only that it stood upright."""
    above = {'fell': False, 'max_tilt_deg': 0.0, 'unsettled_step_share': 0.0, 'deepest': None,
             'max_uncovered_sinkage_m': None}
    assert words(above, -0.05, 'plate') == (
        'upright: base turned at most 0 deg; no body went below the sand surface')
    touched = dict(above, deepest={'body': 'plate', 'sinkage_m': 0.001, 'time_s': 0.1,
                                   'has_plates': True})
    assert words(touched, 0.001, 'plate') == 'upright: base turned at most 0 deg'


def test_diagnostics_carry_the_outcome_and_warn_of_a_fall():
    """/diagnostics (ROS-free fields): the outcome's words and figures as values, level WARN
    once the robot fell, collapsed or sank, OK before."""
    from rft_sim_ros.ros.messages import RunStatus, diagnostic_fields
    from rft_sim_ros.sim.state import SimState
    state = SimState(time=1.0, joint_names=(), joint_positions=np.zeros(0),
                     joint_velocities=np.zeros(0), joint_efforts=np.zeros(0), base_frame='b',
                     base_position=np.zeros(3), base_quaternion_wxyz=np.array([1.0, 0, 0, 0]),
                     base_linear_velocity=np.zeros(3), base_angular_velocity=np.zeros(3),
                     legs=(), zeta=3.75, plates_active=0)
    fallen = {'fell': True, 'fell_at_s': 0.8, 'tilt_limit_deg': 45.0, 'max_tilt_deg': 95.0,
              'final_tilt_deg': 90.0, 'upside_down': False, 'upside_down_at_s': None,
              'final_up_angle_deg': 90.0, 'collapsed': False, 'collapsed_at_s': None,
              'sank': False, 'sank_at_s': None, 'deepest': {'body': 'trunk', 'sinkage_m': 0.02,
                                                  'time_s': 0.9, 'has_plates': True},
              'unsettled_step_share': 0.0, 'max_uncovered_sinkage_m': None,
              'words': 'fell at t = 0.80 s: base turned 95 deg; lying on the sand'}
    fields = diagnostic_fields(state, RunStatus(scene='s', real_time_factor=1.0,
                                                outcome=fallen))
    values = dict(fields.values)
    assert fields.level == 1 and fields.message == 'running'
    assert values['outcome'] == fallen['words'] and values['fell'] == 'true'
    assert float(values['fell_at_s']) == 0.8 and values['deepest_body'] == 'trunk'
    assert values['max_uncovered_sinkage_m'] == 'nan'
    standing = {**fallen, 'fell': False, 'fell_at_s': None, 'deepest': None, 'words': 'upright'}
    fields = diagnostic_fields(state, RunStatus(scene='s', real_time_factor=1.0,
                                                outcome=standing))
    assert fields.level == 0 and dict(fields.values)['fell_at_s'] == 'nan'
    for down in ('upside_down', 'collapsed', 'sank'):  # as much a warning as a fall
        fields = diagnostic_fields(state, RunStatus(scene='s', real_time_factor=1.0, outcome={
            **standing, down: True, f'{down}_at_s': 0.5}))
        values = dict(fields.values)
        assert fields.level == 1 and values[down] == 'true' and float(values[f'{down}_at_s']) == 0.5


def test_start_up_names_the_robots_bodies_without_collision_geoms(tmp_path):
    """A free robot's body without a collision geom (`tail`) is named in a notice, as one
    that passes through the sand; a mocap body and a rig fixed to the world are not."""
    from rft_sim_ros.scenes.config import load_scene
    from rft_sim_ros.sim.simulation import Simulation
    path = tmp_path / 'legged.xml'
    path.write_text(LEGGED.replace('</worldbody>', '<body name="target" mocap="true"/>'
                                   '</worldbody>'))
    sim = Simulation(load_scene(path, {'rft.sand_bodies': ['foot'],
                                       'rft.plates_per_body': 50}))
    [notice] = [n for n in sim.notices if n.startswith('bodies without a collision geom')]
    assert ': tail; should the robot fall onto them they pass through the sand' in notice
    rig = Simulation(load_scene('rail_flat', {'rft.plates_per_body': 50}))
    assert not [n for n in rig.notices if n.startswith('bodies without a collision geom')]


def _set_down_turned(angle_deg, z):
    """(model, data, watch) of FALLER set down turned `angle_deg` about x at height z (m)."""
    model = mujoco.MjModel.from_xml_string(FALLER)
    data = mujoco.MjData(model)
    base = model.body('base').id
    watch = OutcomeWatch(model, base, plated=[base])
    _turn(model, data, angle_deg, z)
    watch.set_down(data)
    watch.start()
    return model, data, watch


def test_a_robot_on_its_back_is_upside_down_never_upright_set_down_so_or_turned_over():
    """The base's z axis against the world's up (REP 103: a standing robot's base frame has
    z up): a robot set down on its back has not turned from there, yet is upside down from
    the first look; one set down upright that turns past 135 deg is upside down from then;
    one set down on its side is not upright; a rigid body (no joints) is not judged."""
    model, data, watch = _set_down_turned(180.0, 0.05)
    sand = Plane(0.0)
    for time in (0.0, 0.5):
        watch.observe(data, sand, time)
    outcome = watch.result(data, sand, steps=10, unsettled=0)
    assert outcome['upside_down'] and outcome['upside_down_at_s'] == 0.0
    assert not outcome['fell'] and watch.down
    assert outcome['up_angle_set_down_deg'] == pytest.approx(180.0)
    assert outcome['final_up_angle_deg'] == pytest.approx(180.0)
    assert outcome['words'].startswith("set down upside down: its base's z axis 180 deg from "
                                       'up, 180 deg at the end; lying on the sand')
    assert 'upright' not in outcome['words']
    _turn(model, data, 0.0, 0.05)
    watch.set_down(data)
    watch.start()
    for time, angle in ((1.0, 60.0), (1.5, 150.0), (2.0, 120.0)):
        _turn(model, data, angle, 0.3)
        watch.observe(data, sand, time)
    outcome = watch.result(data, sand, steps=10, unsettled=0)
    assert outcome['fell_at_s'] == 1.0 and outcome['upside_down_at_s'] == 1.5
    assert outcome['max_up_angle_deg'] == pytest.approx(150.0)
    assert outcome['words'].startswith(
        "fell at t = 1.00 s: base turned 150 deg; upside down at t = 1.50 s: its base's z "
        'axis 120 deg from up at the end (at most 150 deg); ')
    _turn(model, data, 100.0, 0.3)  # (set down on its side: tilted, not upside down)
    watch.set_down(data)
    watch.start()
    watch.observe(data, sand, 0.0)
    outcome = watch.result(data, sand, steps=10, unsettled=0)
    assert not outcome['upside_down'] and not outcome['fell']
    assert outcome['words'].startswith('set down tilted 100 deg from up: base turned at most 0')
    rigid = mujoco.MjModel.from_xml_string(SHAPES)
    data = mujoco.MjData(rigid)
    mujoco.mj_forward(rigid, data)
    watch = OutcomeWatch(rigid, 1, plated=[1])
    _turn(rigid, data, 180.0, 0.5)
    watch.set_down(data)
    watch.start()
    watch.observe(data, sand, 0.0)
    outcome = watch.result(data, sand, steps=10, unsettled=0)
    assert not outcome['upside_down'] and outcome['final_up_angle_deg'] is None
    assert outcome['up_angle_set_down_deg'] is None and 'upright' in outcome['words']


def test_a_robot_set_down_upside_down_is_said_at_start_up_and_in_its_outcome(tmp_path):
    from rft_sim_ros.cli import human_summary
    from rft_sim_ros.scenes.config import load_scene
    from rft_sim_ros.sim.simulation import Simulation
    path = tmp_path / 'legged.xml'
    path.write_text(LEGGED.replace('pos="0 0 0.42"', 'pos="0 0 0.42" euler="180 0 0"'))
    sim = Simulation(load_scene(path, {'rft.sand_bodies': ['foot'],
                                       'rft.plates_per_body': 50}))
    [notice] = [n for n in sim.notices if 'upside down' in n]
    assert notice.startswith('the base (base) is set down upside down: its z axis 180 deg')
    sim.step(100)
    outcome = sim.outcome()
    assert outcome['upside_down'] and outcome['upside_down_at_s'] == 0.0 and sim.down
    summary = {'interrupted': False, 'stable': True, 'outcome': outcome, 'scene': 'legged',
               'sim_time_s': sim.time, 'wall_time_s': 1.0, 'real_time_factor': 0.1,
               'first_step_s': 0.5, 'reason': None, 'metrics': {'x': 1.0}}
    assert human_summary(summary, tmp_path, 1.0)[0].startswith(
        'legged: stable (the robot was upside down)')


def test_lengths_in_the_words_are_in_cm_below_a_metre_and_in_m_above():
    from rft_sim_ros.sim.outcome import length
    assert length(0.147) == '14.7 cm' and length(0.0083) == '0.83 cm'
    assert length(11.9) == '11.9 m' and length(-1.5) == '-1.5 m'


def test_a_robot_set_down_on_its_back_that_rolls_upright_has_not_fallen():
    model, data, watch = _set_down_turned(180.0, 0.3)
    sand = Plane(0.0)
    for time, angle in ((0.0, 180.0), (0.5, 90.0), (1.0, 2.0)):
        _turn(model, data, angle, 0.3)
        watch.observe(data, sand, time)
    outcome = watch.result(data, sand, steps=10, unsettled=0)
    assert not outcome['fell'] and outcome['upside_down'] and outcome['max_tilt_deg'] > 170
    assert outcome['words'].startswith("set down upside down: its base's z axis 180 deg from "
                                       'up, 2 deg at the end; upright again at the end')
