"""Which geoms carry a sand body's plates (rft.plate_geoms), and the start-up notices of
what the sand will not do for a robot: bear it on sand bodies too small (robot/bearing.py),
run MuJoCo's noslip iterations on the constraints it solves. The robot: a 10 kg biped on two
feet whose collision geoms are four 5 mm spheres each (contact points made for rigid ground,
as in many vendors' humanoids) under a visual sole, a 20 x 8 x 2 cm box; and one whose feet
are one such sphere each."""
import numpy as np
import pytest

from rft_sim_ros.robot.bearing import bearing
from rft_sim_ros.sand.geoms import body_plates
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation
from rft_sim_ros.units import zeta_to_si

SOLE = (0.10, 0.04, 0.01)  # half sizes, m
SPHERE = 0.005  # m


def _foot(name, y, corners=((-0.09, -0.03), (-0.09, 0.03), (0.09, -0.03), (0.09, 0.03))):
    corners = ''.join(f'<geom type="sphere" size="{SPHERE}" pos="{x} {c} -0.005" mass="0.01"/>'
                      for x, c in corners)
    return f"""
      <body name="{name}_leg" pos="0 {y} -0.05"><joint name="{name}_hip" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.02" mass="1"/>
        <body name="{name}_foot" pos="0 0 -0.33"><joint name="{name}_ankle" axis="0 1 0"/>
          <geom type="box" size="{' '.join(map(str, SOLE))}" contype="0" conaffinity="0"
                density="0"/>
          {corners}
        </body>
      </body>"""


def _biped(folder, name, **foot):
    (folder / name).write_text(f"""<mujoco><worldbody>
    <body name="trunk" pos="0 0 0.5"><freejoint/>
      <geom type="box" size="0.1 0.15 0.05" mass="7.92"/>
      {_foot('left', 0.1, **foot)}{_foot('right', -0.1, **foot)}
    </body></worldbody></mujoco>""")
    return folder / name


@pytest.fixture(scope='module')
def biped(tmp_path_factory):
    return _biped(tmp_path_factory.mktemp('biped'), 'biped.xml')


def _sim(biped, **overrides):
    return Simulation(load_scene(biped, {'rft.plates_per_body': 400, **overrides}))


def _plate_area(sim):
    """m^2 of the sand bodies' plates (the engine's first; the other bodies' follow)."""
    return sim.engine.areas[:sim.engine.plate_start[len(sim.sand_bodies)]].sum()


def test_contact_spheres_carry_plates_on_the_sole_they_mark(biped):
    """Four 5 mm spheres at the corners of each foot are contact points for rigid ground:
    their plates lie on the spheres' convex hull, whose bottom face is the 18 x 6 cm sole
    between the spheres' lowest points; the soles bear the robot, no notice says it
    sinks, and it stands a few millimetres deep (4 spheres alone: 14 cm)."""
    sim = _sim(biped)
    assert sim.sand_bodies == ('left_foot', 'right_foot')
    foot = sim.model.body('left_foot').id
    plates = body_plates(sim.model, foot, count=400)
    sole = plates.normals[:, 2] < -0.999
    assert plates.areas[sole].sum() == pytest.approx(0.18 * 0.06, rel=0.02)
    assert plates.centroids[sole, 2] == pytest.approx(-0.01, abs=1e-9)
    assert plates.centroids[:, 2].min() == pytest.approx(-0.01, abs=1e-9)
    assert (np.abs(plates.centroids[:, 0]) <= 0.095 + 1e-9).all()
    assert _plate_area(sim) == pytest.approx(2 * plates.total_area)
    assert not [n for n in sim.notices if 'bear' in n]
    sim.step(int(round(0.5 / sim.timestep)))
    depth = sim.engine.surface.height(0.0, 0.0) - (
        sim.data.xpos[sim.engine.body_ids[:2], 2] - 0.01)
    assert (0.0 < depth).all() and (depth < 0.005).all()


def test_a_point_foot_too_small_to_bear_the_robot_is_said(tmp_path):
    """One 5 mm sphere a foot is a point, not a sole: it carries its own plates, which bear
    the robot only ~10 cm deep, and start-up says so and what to do."""
    sim = _sim(_biped(tmp_path, 'points.xml', corners=((0.0, 0.0),)))
    assert sim.sand_bodies == ('left_foot', 'right_foot')
    assert _plate_area(sim) == pytest.approx(2 * 4 * np.pi * SPHERE ** 2, rel=0.1)
    [notice] = [n for n in sim.notices if 'bear' in n]
    assert "robot's 9.94 kg" in notice and 'rft.plate_geoms: visual' in notice


def test_more_plates_than_asked_are_said(biped):
    """Four spheres tessellate into more than 10 plates at the coarsest: the count cannot be
    met, and start-up says how many each body carries (none for a count that is met)."""
    sim = _sim(biped, **{'rft.plates_per_body': 10})
    coarsest = [sim.engine.plate_start[2] // 2] * 2
    assert coarsest[0] > 10
    assert f'plates: left_foot {coarsest[0]}, right_foot {coarsest[1]}, more than asked' in \
        '\n'.join(sim.notices)
    assert not [n for n in _sim(biped).notices if n.startswith('plates:')]


@pytest.mark.parametrize('bodies', ['auto', '*_foot'])
def test_visual_plate_geoms_give_the_feet_their_drawn_soles(biped, bodies):
    sim = _sim(biped, **{'rft.plate_geoms': 'visual', 'rft.sand_bodies': bodies})
    assert sim.sand_bodies == ('left_foot', 'right_foot')
    box = 8 * (SOLE[0] * SOLE[1] + SOLE[0] * SOLE[2] + SOLE[1] * SOLE[2])
    assert _plate_area(sim) == pytest.approx(2 * box, rel=1e-9)  # the spheres: inside it
    assert not [n for n in sim.notices if 'bear' in n]
    # spawn rest set its soles on the sand at rest and let go: the plastic law (zeta A z
    # down, no spring back) stops them where the work of the weight equals that of the
    # sand, m g z = zeta A z^2 / 2: at twice the static depth m g / (zeta A)
    sole_bottom = sim.data.xpos[sim.engine.body_ids[:2], 2] - SOLE[2]
    static = 10 * 9.81 / (zeta_to_si(sim.scene.zeta) * 2 * 4 * SOLE[0] * SOLE[1])
    assert -sole_bottom == pytest.approx([2 * static, 2 * static], rel=0.05)


def test_a_robot_on_sand_bodies_that_reach_deep_enough_gets_no_notice(biped):
    sim = _sim(biped, **{'rft.sand_bodies': ['*_leg', '*_foot']})  # shins carry it
    assert not [n for n in sim.notices if 'bear' in n]


def test_bearing_of_a_horizontal_sole_is_zeta_a_z():
    """A 20 x 8 x 2 cm box sole facing down, level and tilted 30 deg about x (projected
    area cos 30 x; its side facing down adds its own), its shin's lowest point 5 cm above
    its lowest plate."""
    normals = np.array([[0, 0, -1.0], [0, 0, 1.0], [0, -1.0, 0], [0, 1.0, 0]])
    centroids = np.array([[0, 0, -0.01], [0, 0, 0.01], [0, -0.04, 0], [0, 0.04, 0]])
    areas = np.array([0.016, 0.016, 0.004, 0.004])
    sole, zeta, gravity = (normals, centroids, areas), zeta_to_si(2.0), (0, 0, -9.81)
    flat = bearing(10.0, gravity, zeta, [(np.array([0, 0, 0.3]), np.eye(3))], [sole],
                   others_lowest=0.34)
    assert flat.area_m2 == pytest.approx(0.016)
    assert flat.depth_m == pytest.approx(98.1 / (zeta * 0.016))
    assert flat.clearance_m == pytest.approx(0.05) and not flat.sinks
    heavy = bearing(1000.0, gravity, zeta, [(np.array([0, 0, 0.3]), np.eye(3))], [sole],
                    others_lowest=0.34)
    assert heavy.depth_m > 0.05 and heavy.sinks
    alone = bearing(1000.0, gravity, zeta, [(np.zeros(3), np.eye(3))], [sole])
    assert not alone.sinks  # a body alone (a plate dropped): nothing else to pass through
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    tilted = bearing(10.0, gravity, zeta, [(np.zeros(3), np.array([[1, 0, 0], [0, c, -s],
                                                                   [0, s, c]]))], [sole])
    assert tilted.area_m2 == pytest.approx(0.016 * c + 0.004 * s)
    upward = bearing(10.0, gravity, zeta, [(np.zeros(3), np.eye(3))],
                     [(normals[1:2], centroids[1:2], areas[1:2])], others_lowest=1.0)
    assert upward.depth_m == np.inf and upward.sinks


def test_noslip_iterations_the_sand_solve_does_not_run_are_said(biped, tmp_path):
    path = tmp_path / 'noslip.xml'
    path.write_text(biped.read_text().replace('<mujoco>',
                                              '<mujoco><option noslip_iterations="3"/>'))
    said = [n for n in _sim(path).notices if 'noslip' in n]
    assert len(said) == 1 and '(3)' in said[0]
    explicit = _sim(path, **{'rft.low_velocity.method': 'ema'})
    assert not [n for n in explicit.notices if 'noslip' in n]


def test_other_bodies_plates_beyond_the_density_are_said(biped):
    """The legs' capsules tessellate no coarser than ~100 triangles where 0.001 per mm^2
    asks ~40: start-up says how many plates the other bodies carry beyond the density."""
    sim = _sim(biped)
    assert set(sim.other_bodies) == {'trunk', 'left_leg', 'right_leg'}
    engine, start = sim.engine, sim.engine.plate_start
    first = len(sim.sand_bodies)
    counts = np.diff(start[first:])
    asked = [max(1, round(0.001 * engine.areas[a:b].sum() * 1e6))
             for a, b in zip(start[first:-1], start[first + 1:])]
    assert (counts >= asked).all() and counts.sum() > sum(asked)
    [notice] = [n for n in sim.notices if n.startswith('other bodies:')]
    assert (f'carry {counts.sum()} plates (0.001 per mm^2, {counts.sum() - sum(asked)} more '
            'than 0.001 per mm^2 asks') in notice
