"""sim/outcome.py: the lowest point of each geom type (a mesh's too), exact against a dense
sampling of its surface; the tilt, fall time and deepest point a watch records; the words."""
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
    watch.start(data, 1.0)
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


def test_the_words_say_a_body_left_under_the_sand():
    outcome = {'fell': True, 'fell_at_s': 0.8, 'max_tilt_deg': 95.0, 'unsettled_step_share': 0,
               'deepest': {'body': 'pelvis', 'sinkage_m': 1.2, 'time_s': 1.5,
                           'has_plates': False},
               'max_uncovered_sinkage_m': 1.2}
    assert words(outcome, 0.9, 'pelvis') == (
        'fell at t = 0.80 s: base turned 95 deg; pelvis ends 90 cm below the sand surface; '
        'deepest: pelvis 120 cm below the surface at t = 1.50 s (no plates: it passed through)')


def test_the_words_say_no_body_reached_the_sand():
    """A run that ends before the robot touches the sand (a short drop, a robot held above
    it) says so, rather than only that it stood upright."""
    above = {'fell': False, 'max_tilt_deg': 0.0, 'unsettled_step_share': 0.0, 'deepest': None,
             'max_uncovered_sinkage_m': None}
    assert words(above, -0.05, 'plate') == (
        'upright: base turned at most 0 deg; no body has reached the sand')
    touched = dict(above, deepest={'body': 'plate', 'sinkage_m': 0.001, 'time_s': 0.1,
                                   'has_plates': True})
    assert words(touched, 0.001, 'plate') == 'upright: base turned at most 0 deg'


def test_diagnostics_carry_the_outcome_and_warn_of_a_fall():
    """/diagnostics (ROS-free fields): the outcome's words and figures as values, level WARN
    once the robot fell, OK before."""
    from rft_sim_ros.ros.messages import RunStatus, diagnostic_fields
    from rft_sim_ros.sim.state import SimState
    state = SimState(time=1.0, joint_names=(), joint_positions=np.zeros(0),
                     joint_velocities=np.zeros(0), joint_efforts=np.zeros(0), base_frame='b',
                     base_position=np.zeros(3), base_quaternion_wxyz=np.array([1.0, 0, 0, 0]),
                     base_linear_velocity=np.zeros(3), base_angular_velocity=np.zeros(3),
                     legs=(), zeta=3.75, plates_active=0)
    fallen = {'fell': True, 'fell_at_s': 0.8, 'tilt_limit_deg': 45.0, 'max_tilt_deg': 95.0,
              'final_tilt_deg': 90.0, 'deepest': {'body': 'trunk', 'sinkage_m': 0.02,
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
