"""Sand surfaces (plane, slope, height grid, MJCF hfield) and the zeta map."""
import json

import mujoco
import numpy as np
import pytest

from test_engine import _arm, _random_state

from rft_sim_ros.rft import body_wrench
from rft_sim_ros.rft.plates import Plates
from rft_sim_ros.sand.deformable import DeformableSand
from rft_sim_ros.sand.deformable_codes import COUNT
from rft_sim_ros.sand.engine import LowVelocity, SandEngine
from rft_sim_ros.sand.geoms import body_plates
from rft_sim_ros.sand.surface import (HeightGrid, Plane, Slope, block_maximum, block_minimum,
                                      heights_digest, surface_from_settings, tile_planes,
                                      window_extremes, window_span)
from rft_sim_ros.sand.surface_kernels import window_range
from rft_sim_ros.sand.zeta_map import ZetaMap, zeta_map_from_settings
from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.sim.runner import run_scene
from rft_sim_ros.sim.simulation import Simulation


#: A slope, a rippled height grid, a tilted, gently curved one (bounded by the tiles'
#: planes: `surface.tile_planes`) and a level shelf meeting a ramp under the plates (tiles
#: holding both: bodies over the level part bounded by a tile's plane), for the tests of
#: depth below a shaped surface.
SHAPED = [
    Slope(0.02, angle_deg=12.0, downhill_deg=35.0),
    HeightGrid(0.03 * np.sin(np.linspace(0, 6, 50))[:, None] * np.cos(np.linspace(0, 5, 60)),
               size=(1.5, 1.2), center=(0.05, 0.0)),
    HeightGrid(0.02 - 0.2 * np.linspace(-0.6, 0.6, 121)[None, :]
               + 0.005 * np.cos(np.linspace(0, 4, 101))[:, None], size=(1.2, 1.0)),
    HeightGrid(np.tile(0.02 + 0.3 * np.maximum(np.linspace(-0.5, 0.5, 101) - 0.12, 0.0),
                       (81, 1)), size=(1.0, 0.8))]


def _engine(surface=None, zeta_map=None, **options):
    return _arm(surface=surface, zeta_map=zeta_map, **options)


def _wrenches(surface, seed, zeta_map=None):
    model, data, engine = _engine(surface, zeta_map, low_velocity=LowVelocity(method='none'))
    _random_state(model, data, seed)
    mujoco.mj_step1(model, data)
    engine.apply()
    return model, data, engine, engine.body_wrenches.copy()


def _numpy_height(surface, x, y):
    """The surface's height at world (x, y) computed here with numpy, independently of the
    compiled look-up the engine (and `HeightGrid.height`) use: bilinear between a grid's
    nodes, its edge values continued; a deformable bed's base beyond the bed."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if isinstance(surface, DeformableSand):
        (x0, y0), (sx, sy) = surface.origin, surface.size
        inside = (x >= x0) & (x <= x0 + sx) & (y >= y0) & (y <= y0 + sy)
        return np.where(inside, _bilinear(surface, x, y), _numpy_height(surface.base, x, y))
    if isinstance(surface, HeightGrid):
        return _bilinear(surface, x, y)
    return surface.height(x, y)


def _bilinear(grid, x, y):
    ny, nx = grid.grid.shape
    u = np.clip((x - grid.origin[0]) / grid.spacing[0], 0.0, nx - 1)
    v = np.clip((y - grid.origin[1]) / grid.spacing[1], 0.0, ny - 1)
    i = np.minimum(u.astype(int), nx - 2)
    j = np.minimum(v.astype(int), ny - 2)
    fu, fv = u - i, v - j
    g = grid.grid
    return ((1 - fv) * ((1 - fu) * g[j, i] + fu * g[j, i + 1])
            + fv * ((1 - fu) * g[j + 1, i] + fu * g[j + 1, i + 1]))


def test_a_grids_height_is_bilinear_between_its_nodes_and_continues_its_edges():
    rng = np.random.default_rng(4)
    grid = HeightGrid(rng.normal(size=(23, 31)), size=(0.9, 0.6), center=(0.2, -0.1))
    x, y = rng.uniform(-0.6, 1.0, (3, 400)), rng.uniform(-0.7, 0.5, (3, 400))  # some beyond
    assert np.allclose(grid.height(x, y), _bilinear(grid, x, y), rtol=0, atol=1e-13)
    nodes_x = grid.origin[0] + grid.spacing[0] * np.arange(31)
    nodes_y = grid.origin[1] + grid.spacing[1] * np.arange(23)
    assert np.allclose(grid.height(*np.meshgrid(nodes_x, nodes_y)), grid.grid, atol=1e-14)
    assert isinstance(grid.height(0.2, -0.1), float)  # a point in, a number out
    far = [1e19, 1e300, np.inf]  # (beyond any integer node coordinate: the edge still)
    assert np.allclose(grid.height(far, [-0.1] * 3), _bilinear(grid, 1.0, -0.1), rtol=0,
                       atol=1e-13)


def test_a_rigid_grid_is_read_only_and_refuses_a_size_or_centre_that_is_not_finite():
    """The engine derives the grid's bounds once: a rigid grid's heights and bounds cannot be
    changed in place (that gave forces of the old surface, silently); deformable sand's
    change through its kernels, or by hand through `editing`, which keeps its bounds (a
    hand edit in place would not: read-only too). A NaN or infinite size or centre is said
    to be one."""
    grid = HeightGrid(np.zeros((5, 6)), size=(0.5, 0.4))
    bed = DeformableSand(grid, size=(0.2, 0.2), cell=0.02)
    for array in (grid.grid, grid.block_max, grid.block_min, bed.grid, bed.block_max,
                  bed.block_min, bed.pristine):
        with pytest.raises(ValueError, match='read-only'):
            array[0, 0] = 0.03
    with bed.editing() as heights:
        heights[2, 3] += 0.01
    assert bed.grid[2, 3] == 0.01 and bed.block_max.max() == 0.01 and bed.pristine.max() == 0
    for size in ((np.nan, 2.0), (np.inf, 2.0)):
        with pytest.raises(ValueError, match=r'sand.surface.size must be \[x, y\] > 0 m, finite'):
            HeightGrid(np.zeros((5, 6)), size=size)
    with pytest.raises(ValueError, match=r"a height grid's center must be \[x, y\] m, finite"):
        HeightGrid(np.zeros((5, 6)), size=(0.5, 0.4), center=(np.nan, 0.0))


def _assert_reference_law(model, data, engine, wrenches, surface):
    """Each body's engine wrench equals the reference law's (`rft.body_wrench`) with every
    plate's depth measured vertically below the surface's height at its own (x, y)
    (`_numpy_height`)."""
    for i, name in enumerate(engine.body_names):
        body = model.body(name).id
        velocity = np.zeros(6)
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, body, velocity, 0)
        plates = body_plates(model, body, count=300)
        rotation = data.xmat[body].reshape(3, 3)
        world = plates.centroids @ rotation.T + data.xpos[body]
        heights = _numpy_height(surface, world[:, 0], world[:, 1])
        force, torque = body_wrench(plates, data.xpos[body], rotation, velocity[3:],
                                    velocity[:3], 2.0, surface_height=heights)
        torque_about_com = torque + np.cross(data.xpos[body] - data.xipos[body], force)
        assert np.allclose(wrenches[i, :3], force, rtol=1e-9, atol=1e-12)
        assert np.allclose(wrenches[i, 3:], torque_about_com, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize('seed', range(3))
def test_a_flat_height_grid_gives_exactly_the_planes_forces(seed):
    h = 0.0375
    grid = HeightGrid(np.full((41, 31), h), size=(1.2, 1.6), center=(0.1, -0.05))
    *_, plane = _wrenches(Plane(h), seed)
    *_, engine, flat_grid = _wrenches(grid, seed)
    assert engine.plates_active > 0
    assert np.array_equal(plane, flat_grid)


def test_a_body_whose_plates_lie_at_its_origin_reads_a_rigid_grid():
    """A sand body of radius 0 (its one plate at its origin: a probe) on a rigid grid meets
    the grid under it, as any body does: a horizontal plate pushed straight down 1 mm below
    the surface feels zeta A z. A body without plates is refused with its name."""
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body name="probe" pos="0 0 1"><freejoint/>'
        '<geom size="0.01" mass="0.1"/></body></worldbody></mujoco>')
    data = mujoco.MjData(model)
    grid = HeightGrid(0.3 + 0.01 * np.tile(np.arange(21.0), (21, 1)), size=(2.0, 2.0))
    probe = Plates(np.zeros((1, 3)), np.array([[0.0, 0.0, -1.0]]), np.array([1e-4]))
    engine = SandEngine(model, data, {'probe': probe}, zeta=2.0, surface=grid,
                        low_velocity=LowVelocity(method='none'))
    x, y = 0.05, 0.02
    data.qpos[:3] = x, y, grid.height(x, y) - 1e-3
    data.qvel[2] = -0.01
    mujoco.mj_step1(model, data)
    engine.apply()
    assert engine.body_wrenches[0, 2] == pytest.approx(2.0e6 * 1e-4 * 1e-3, rel=1e-9)
    nothing = Plates(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    with pytest.raises(ValueError, match='sand bodies without plates: probe'):
        SandEngine(model, data, {'probe': nothing}, zeta=2.0, surface=grid)


@pytest.mark.parametrize('seed', range(3))
def test_a_grid_level_under_the_bodies_only_gives_exactly_the_planes_forces(seed):
    """Blocks level at h under the bodies (read without a look-up), a hill elsewhere."""
    h = 0.0375
    heights = np.full((41, 31), h)
    heights[:4, :4] += 0.2
    grid = HeightGrid(heights, size=(1.2, 1.6), center=(0.1, -0.05))
    assert (grid.block_max != grid.block_min).any()
    *_, plane = _wrenches(Plane(h), seed)
    *_, engine, level = _wrenches(grid, seed)
    assert engine.plates_active > 0
    assert np.array_equal(plane, level)


@pytest.mark.parametrize('seed', range(3))
@pytest.mark.parametrize('surface', SHAPED)
def test_depth_below_a_shaped_surface_is_vertical_below_the_local_height(surface, seed):
    """The engine's wrench equals the reference law with each plate's depth measured
    vertically below the surface height at its own (x, y)."""
    model, data, engine, wrenches = _wrenches(surface, seed)
    assert engine.plates_active > 0
    _assert_reference_law(model, data, engine, wrenches, surface)


#: Per _random_state seed: (x, y) m near the middle of the plates in the sand.
IN_SAND = {0: (0.065, 0.095), 1: (0.2, 0.008), 2: (0.145, -0.006)}


@pytest.mark.parametrize('seed', range(3))
@pytest.mark.parametrize('base', SHAPED)
def test_beyond_a_deformable_bed_its_base_surface_carries_the_plates(base, seed):
    """A deformable bed over part of the plates in the sand (its edge through their middle):
    the plates over the bed read the bed, the others its base (a slope, a grid), each at its
    own (x, y) as the reference law; only those over the bed mark footprints."""
    x, y = IN_SAND[seed]
    bed = DeformableSand(base, size=(0.1, 0.2), cell=0.01, center=(x - 0.05, y))
    model, data, engine, wrenches = _wrenches(bed, seed)
    assert bed.plates_outside > 0 and bed.state[COUNT] > 0  # plates beyond it, and over it
    beyond = np.array([[x + 0.01, y], [x + 0.3, y + 0.2], [x - 0.5, y - 0.4]])
    assert np.array_equal(bed.height(beyond[:, 0], beyond[:, 1]),
                          base.height(beyond[:, 0], beyond[:, 1]))
    _assert_reference_law(model, data, engine, wrenches, bed)


@pytest.mark.parametrize('seed', range(3))
def test_across_a_grids_edge_its_edge_heights_continue(seed):
    """A rippled grid whose edge runs through the middle of the plates in the sand: bodies
    a cell inside it (read without clamping), bodies across its edge and beyond it (edge
    heights continued) all feel the reference law at their plates' own heights."""
    x, y = IN_SAND[seed]
    u, v = np.meshgrid(np.linspace(0, 3, 21), np.linspace(0, 2, 31))
    grid = HeightGrid(0.02 * np.sin(4 * u) * np.cos(5 * v), size=(0.2, 0.3),
                      center=(x - 0.1, y))
    model, data, engine, wrenches = _wrenches(grid, seed)
    assert engine.plates_active > 0
    _assert_reference_law(model, data, engine, wrenches, grid)


@pytest.mark.parametrize('seed', range(3))
def test_far_from_its_deformable_bed_a_slope_acts_as_the_slope_itself(seed):
    """Bodies wholly beyond the bed: they are found in the sand by the base's own bounds
    (a 12 deg slope rising under them) and feel what the rigid slope gives them."""
    slope = Slope(0.02, angle_deg=12.0, downhill_deg=35.0)
    bed = DeformableSand(slope, size=(0.2, 0.2), cell=0.01, center=(3.0, 3.0))
    *_, rigid = _wrenches(slope, seed)
    *_, engine, far = _wrenches(bed, seed)
    assert engine.plates_active > 0 and bed.plates_outside > 0 and bed.state[COUNT] == 0
    assert np.allclose(far, rigid, rtol=1e-9, atol=1e-12)


def test_bodies_above_a_hill_are_skipped_but_not_bodies_in_it():
    heights = np.zeros((101, 101))
    heights[45:56, 45:56] = 0.4  # a 0.2 m tower of sand around the origin
    hill = HeightGrid(heights, size=(2.0, 2.0))
    for x, inside in ((0.0, True), (0.8, False)):
        model, data, engine = _engine(hill, low_velocity=LowVelocity(method='none'))
        data.qpos[:3] = [x - 0.2, 0.0, 0.3]  # the lower leg hangs over (x, 0)
        data.qvel[2] = -0.1
        mujoco.mj_step1(model, data)
        engine.apply()
        assert (engine.plates_active > 0) == inside


def test_block_maximum_and_minimum_bound_every_node():
    rng = np.random.default_rng(1)
    grid = rng.normal(size=(37, 29))
    high, low = block_maximum(grid, block=8), block_minimum(grid, block=8)
    for j in range(37):
        for i in range(29):
            for bj in {j // 8, max(j - 1, 0) // 8}:  # a node at a block's end is in both
                for bi in {i // 8, max(i - 1, 0) // 8}:
                    assert low[bj, bi] <= grid[j, i] <= high[bj, bi]


@pytest.mark.parametrize('span', [(0, 0), (1, 3), (4, 4), (6, 2), (40, 50)])
def test_window_extremes_are_each_windows_highest_and_lowest_node(span):
    grid = np.random.default_rng(3).normal(size=(23, 31))
    high, low = window_extremes(grid, span)
    assert high.shape == low.shape == grid.shape
    for j in range(23):
        for i in range(31):
            window = grid[j:j + span[1] + 1, i:i + span[0] + 1]
            assert (high[j, i], low[j, i]) == (window.max(), window.min())


@pytest.mark.parametrize('spacing', [(0.01, 0.01), (0.013, 0.007)])
def test_a_window_bounds_the_surface_over_any_square_up_to_its_radius(spacing):
    """The window at a square's first node (`window_range`, spans from `window_span`) holds
    every node of the cells the square touches (those a bilinear look-up in it reads), also
    where the square reaches beyond the grid's edge (whose heights continue)."""
    rng = np.random.default_rng(4)
    size = (spacing[0] * 36, spacing[1] * 40)
    grid = HeightGrid(rng.normal(size=(41, 37)), size=size, center=(0.1, -0.2))
    radius = 0.023
    high, low = window_extremes(grid.grid, window_span(radius, spacing))
    (x0, y0), (dx, dy) = grid.origin, grid.spacing
    for _ in range(2000):
        x = rng.uniform(x0 - 0.05, x0 + size[0] + 0.05)
        y = rng.uniform(y0 - 0.05, y0 + size[1] + 0.05)
        r = radius * min(1.0, rng.uniform(0.5, 1.5))  # (often the largest)
        bottom, top = window_range(high, low, x0, y0, 1 / dx, 1 / dy, x, y, r)
        # the nodes of the cells the square touches, from the first to one past the last
        # (clamped to the grid; `square_nodes`), computed here independently
        (u0, u1), (v0, v1) = [np.clip((np.array([c - r, c + r]) - o) / d, 0, n - 1).astype(int)
                              for c, o, d, n in ((x, x0, dx, 37), (y, y0, dy, 41))]
        nodes = grid.grid[v0:v1 + 2, u0:u1 + 2]
        assert bottom <= nodes.min() and nodes.max() <= top
        px = rng.uniform(x - r, x + r, 50)
        py = rng.uniform(y - r, y + r, 50)
        surface = grid.height(px, py)  # (bilinear: within its nodes up to rounding)
        assert bottom - 1e-12 <= surface.min() and surface.max() <= top + 1e-12


@pytest.mark.parametrize('shape', ['tilted', 'random', 'level'])
def test_tile_planes_bound_the_surface_over_each_tile(shape):
    """Over each tile (nodes [t*step, t*step + 2*step], clipped), the bilinear surface never
    exceeds the tile's plane and touches it at a node; a tilted, gently curved grid gets
    usable planes, a random one none, and a level one none (its blocks read it as level)."""
    rng = np.random.default_rng(2)
    x, y = np.meshgrid(np.linspace(0, 1, 43), np.linspace(0, 1, 31))
    heights = {'tilted': 0.2 * x - 0.1 * y + 0.01 * np.sin(3 * x) * np.cos(2 * y),
               'random': rng.normal(size=x.shape), 'level': np.full(x.shape, 0.37)}[shape]
    grid = HeightGrid(heights, size=(0.84, 0.6), center=(0.3, -0.2))
    step = 5
    tiles = tile_planes(grid.grid, grid.origin, grid.spacing, step)
    ntx = (43 - 2) // step + 1
    assert tiles.shape == (((31 - 2) // step + 1) * ntx, 4)
    assert tiles[:, 3].all() if shape == 'tilted' else not tiles[:, 3].any()
    (x0, y0), (dx, dy) = grid.origin, grid.spacing
    for row, (a, gx, gy, _) in enumerate(tiles):
        tj, ti = divmod(row, ntx)
        i1, j1 = min(ti * step + 2 * step, 42), min(tj * step + 2 * step, 30)
        u = rng.uniform(ti * step, i1, 200)
        v = rng.uniform(tj * step, j1, 200)
        px, py = x0 + u * dx, y0 + v * dy
        assert np.all(grid.height(px, py) <= a + gx * px + gy * py + 1e-12)
        nodes_x = x0 + dx * np.arange(ti * step, i1 + 1)
        nodes_y = y0 + dy * np.arange(tj * step, j1 + 1)
        nx_, ny_ = np.meshgrid(nodes_x, nodes_y)
        gap = a + gx * nx_ + gy * ny_ - grid.grid[tj * step:j1 + 1, ti * step:i1 + 1]
        assert gap.min() == pytest.approx(0.0, abs=1e-12)


def test_slope_heights_and_normal():
    slope = Slope(0.1, angle_deg=10.0, downhill_deg=90.0)  # falls towards +y
    assert slope.height(3.0, 0.0) == pytest.approx(0.1)
    assert slope.height(0.0, 1.0) == pytest.approx(0.1 - np.tan(np.radians(10)))
    assert np.allclose(slope.normal(0.2, 0.3), [0, np.sin(np.radians(10)), np.cos(np.radians(10))])
    with pytest.raises(ValueError, match='angle_deg'):
        Slope(0.0, angle_deg=95.0)


def test_a_surfaces_steepest_inclination():
    """A slope's angle; a grid's steepest point of its bilinear surface, at a cell corner
    (z = x y over a unit cell: gradient (1, 1) at (1, 1), 54.7 deg; a tilted plane sampled on
    a grid: its own angle); a plane 0; deformable sand, its bed's or its base's."""
    assert Slope(0.0, 12.5, 40.0).steepest_deg() == 12.5 and Plane(0.3).steepest_deg() == 0.0
    x, y = np.meshgrid(np.linspace(0, 1, 2), np.linspace(0, 1, 2))
    assert HeightGrid(x * y, (1.0, 1.0)).steepest_deg() == pytest.approx(
        np.degrees(np.arctan(np.sqrt(2))))
    x, y = np.meshgrid(np.linspace(-1, 1, 21), np.linspace(-0.5, 0.5, 11))
    assert HeightGrid(0.3 * x - 0.4 * y, (2.0, 1.0)).steepest_deg() == pytest.approx(
        np.degrees(np.arctan(0.5)))
    # deformable sand: the steeper of its bed and the base beyond it (a bed on a level
    # patch of a 25 deg slope's grid is 25 deg steep at its steepest, beyond the bed)
    ramp = HeightGrid(np.tan(np.radians(25.0)) * np.maximum(x - 0.5, 0.0), (2.0, 1.0))
    bed = DeformableSand(ramp, size=(0.4, 0.4), cell=0.02, center=(-0.5, 0.0))
    assert HeightGrid(bed.grid, bed.size).steepest_deg() == 0.0
    assert bed.steepest_deg() == pytest.approx(25.0)


@pytest.mark.parametrize('angle, said', [(15.0, False), (25.0, True)])
def test_a_surface_steeper_than_the_slopes_checked_is_said_at_start_up(angle, said):
    sim = Simulation(load_scene('plate_drop', {'sand.surface.type': 'slope',
                                               'sand.surface.angle_deg': angle}))
    notices = [n for n in sim.notices if 'beyond the slopes checked' in n]
    assert bool(notices) == said
    if said:
        assert notices[0].startswith('the sand surface is 25 deg steep at its steepest: beyond '
                                     'the slopes checked (up to 20 deg)')


HFIELD = """
<mujoco>
  <asset><hfield name="dunes" nrow="3" ncol="4" size="0.6 0.4 0.05 0.01"
                 elevation="0 1 2 3  1 2 3 4  0 0 4 4"/></asset>
  <worldbody><geom name="terrain" type="hfield" hfield="dunes" pos="0.1 -0.2 0.02"/></worldbody>
</mujoco>"""


def test_lowest_and_highest_surface_point_over_a_rectangle():
    """`bounds` (lowest, highest) and `highest`: exact on the plane and the slope (corners),
    and on a grid the lowest and highest node of the cells the rectangle touches: never
    above / below the surface inside it, exact on nodes, equal where the grid is level."""
    rng = np.random.default_rng(3)
    grid = HeightGrid(rng.uniform(0.0, 0.05, (9, 12)), (1.1, 0.8), (0.2, -0.1))
    slope = Slope(0.1, angle_deg=12.0, downhill_deg=200.0)
    assert Plane(0.3).highest(-1.0, 2.0, -3.0, 4.0) == 0.3
    assert Plane(0.3).bounds(-1.0, 2.0, -3.0, 4.0) == (0.3, 0.3)
    for x0, y0, wx, wy in rng.uniform([-0.8, -0.6, 0.0, 0.0], [0.8, 0.4, 0.3, 0.3], (30, 4)):
        xs, ys = np.meshgrid(np.linspace(x0, x0 + wx, 41), np.linspace(y0, y0 + wy, 41))
        for surface in (slope, grid):
            low, top = surface.bounds(x0, x0 + wx, y0, y0 + wy)
            assert top == surface.highest(x0, x0 + wx, y0, y0 + wy)
            assert top >= surface.height(xs, ys).max() - 1e-15
            assert low <= surface.height(xs, ys).min() + 1e-15
        assert slope.bounds(x0, x0 + wx, y0, y0 + wy) == pytest.approx(
            (slope.height(xs, ys).min(), slope.height(xs, ys).max()), abs=1e-15)
    # a rectangle from node (2, 3) to node (5, 6) (a hair inside, against rounding): exactly
    # its nodes' lowest and highest
    (ox, oy), (dx, dy) = grid.origin, grid.spacing
    hair = 1e-9
    assert grid.bounds(ox + 2 * dx + hair, ox + 5 * dx - hair, oy + 3 * dy + hair,
                       oy + 6 * dy - hair) == \
        (grid.grid[3:7, 2:6].min(), grid.grid[3:7, 2:6].max())
    level = HeightGrid(np.full((4, 4), 0.07), (0.3, 0.3))
    assert level.bounds(-0.1, 0.1, -0.1, 0.1) == (0.07, 0.07)
    assert grid.highest(-9.0, -8.0, -9.0, -8.0) == grid.grid[0, 0]  # outside: edge continued
    # deformable sand: its bed, and beyond the bed its base (a slope rising to -x here)
    bed = DeformableSand(slope, size=(0.4, 0.4), cell=0.02)
    with bed.editing() as heights:
        heights[10, 10] += 0.05  # a pile in the middle of the bed
    assert bed.highest(-0.05, 0.05, -0.05, 0.05) == pytest.approx(bed.grid[10, 10])
    assert bed.highest(0.5, 0.6, 0.0, 0.1) == pytest.approx(slope.highest(0.5, 0.6, 0.0, 0.1))
    assert bed.highest(0.1, 0.5, 0.0, 0.1) >= slope.highest(0.1, 0.5, 0.0, 0.1)
    assert bed.bounds(0.1, 0.5, 0.0, 0.1)[0] <= slope.bounds(0.1, 0.5, 0.0, 0.1)[0]


@pytest.mark.parametrize('surface', [{'type': 'slope', 'angle_deg': 15.0, 'downhill_deg': 30.0},
                                     {'type': 'slope', 'angle_deg': 15.0, 'downhill_deg': 210.0},
                                     {'type': 'grid', 'file': 'ridges.npy', 'size': [1.0, 1.0]}])
def test_spawn_clears_the_surface_under_every_sand_body(surface, tmp_path):
    """`robot.spawn: drop:H` on a slope or a grid (ridges 8 cm high): no plate of any sand
    body starts in the sand or less than H above the surface under it, and the lowest starts
    at most a few cm higher (each geom's bounding box is kept H above the surface's highest
    point under the box; the sandbot's feet are 4 cm boxes, turned with the robot to the
    slope, or by 10.6 deg to the plane under its feet on the ridges, whose flanks are 40 deg
    steep: there the highest ground under a foot's box lies up to 3.5 cm above that under its
    lowest corner)."""
    from pathlib import Path
    x = np.linspace(-0.5, 0.5, 51)
    np.save(tmp_path / 'ridges.npy', np.tile(0.04 * np.sin(2 * np.pi * x / 0.3), (51, 1)))
    package = Path(__file__).parent / 'robots' / 'sandbot_description'
    for height in (0.02, 0.0):
        overrides = {'robot.package_paths': {'sandbot_description': str(package)},
                     'rft.plates_per_body': 100, 'robot.spawn': f'drop:{height}',
                     **{f'sand.surface.{key}': str(tmp_path / value) if key == 'file' else value
                        for key, value in surface.items()}}
        sim = Simulation(load_scene(package / 'urdf' / 'sandbot.urdf.xacro', overrides))
        engine, data = sim.engine, sim.data
        lowest = np.inf
        for n, body in enumerate(engine.body_ids):
            local = engine.local_pos[engine.plate_start[n]:engine.plate_start[n + 1]]
            world = data.xpos[body] + local @ data.xmat[body].reshape(3, 3).T
            gap = world[:, 2] - engine.surface.height(world[:, 0], world[:, 1])
            lowest = min(lowest, gap.min())
        assert height - 1e-9 <= lowest < height + 0.06


def test_spawn_turns_the_robot_to_the_plane_of_the_surface_under_its_sand_bodies():
    """`align_to`: the smallest rotation taking world z to the normal of the least-squares
    plane under the sand bodies: on a slope that is the slope's normal (a body upright before
    stands along it after, turned about the sand bodies' lowest point); on a plane, and on a
    surface whose fit is level but for rounding, nothing is touched, bit for bit."""
    from rft_sim_ros.robot.pose import align_to, surface_gradient
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><worldbody><body name="base" pos="0.3 -0.2 0.5"><freejoint/>'
        '<geom type="box" size="0.2 0.1 0.02"/><body name="foot" pos="0.15 0 -0.1">'
        '<geom type="sphere" size="0.02"/></body></body></worldbody></mujoco>')
    data = mujoco.MjData(model)
    base, foot = model.body('base').id, model.body('foot').id
    slope = Slope(0.05, angle_deg=14.0, downhill_deg=120.0)
    assert surface_gradient(slope.height, (-1.0, 1.0, -0.5, 0.5)) == pytest.approx(
        slope.gradient, abs=1e-12)
    before = data.qpos.copy()
    assert align_to(model, data, base, [base, foot], Plane(0.2).height) == 0.0
    assert np.array_equal(data.qpos, before)
    mujoco.mj_kinematics(model, data)
    foot_before = data.xpos[foot].copy()
    turned = align_to(model, data, foot, [foot], slope.height)  # (a foot's plates only)
    assert np.degrees(turned) == pytest.approx(14.0)
    up = data.xmat[base].reshape(3, 3)[:, 2]
    np.testing.assert_allclose(up, slope.normal(0.0, 0.0), atol=1e-12)
    # turned about the foot's lowest point: the foot stays over the ground the plane was
    # fitted to (within its 2 cm radius), the base above it swings
    assert np.linalg.norm(data.xpos[foot] - foot_before) < 0.006
    assert np.linalg.norm(data.qpos[:3] - before[:3]) > 0.02
    wave = 0.01 * np.cos(np.linspace(-2 * np.pi, 2 * np.pi, 41))  # symmetric about the foot:
    ripples = HeightGrid(np.tile(wave, (41, 1)), (2.0, 2.0), center=tuple(foot_before[:2]))
    # a fit whose gradient is zero but for rounding
    data.qpos[:] = before
    assert align_to(model, data, base, [foot], ripples.height) == 0.0
    assert np.array_equal(data.qpos, before)


def test_mjcf_hfield_heights_match_mujocos_own_ray_casts():
    model = mujoco.MjModel.from_xml_string(HFIELD)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    grid = HeightGrid.from_mjcf_hfield(model, 'terrain')
    rng = np.random.default_rng(0)
    geomid = np.zeros(1, dtype=np.int32)
    for x, y in rng.uniform([-0.45, -0.55], [0.65, 0.15], size=(20, 2)):
        distance = mujoco.mj_ray(model, data, np.array([x, y, 1.0]), np.array([0, 0, -1.0]),
                                 None, 1, -1, geomid)
        # MuJoCo triangulates each cell; bilinear agrees at nodes and along cell edges and
        # lies within the cell's node range inside it
        assert abs((1.0 - distance) - grid.height(x, y)) < 0.05 * 0.5
    ny, nx = grid.grid.shape
    for j in range(ny):
        for i in range(nx):
            x = grid.origin[0] + i * grid.spacing[0]
            y = grid.origin[1] + j * grid.spacing[1]
            start = np.array([np.clip(x, -0.499, 0.699), np.clip(y, -0.599, 0.199), 1.0])
            distance = mujoco.mj_ray(model, data, start, np.array([0, 0, -1.0]), None, 1, -1,
                                     geomid)
            assert 1.0 - distance == pytest.approx(grid.height(*start[:2]), abs=2e-3)


HFIELD_IN_A_BODY = """
<mujoco>
  <asset><hfield name="dunes" nrow="3" ncol="4" size="0.6 0.4 0.05 0.01"
                 elevation="0 1 2 3  1 2 3 4  0 0 4 4"/></asset>
  <worldbody>
    <body name="ground" pos="0.3 0.1 0.0" euler="0 0 {body_deg}">
      <body name="terrain_mount" pos="0.05 -0.1 0.02">
        <geom name="terrain" type="hfield" hfield="dunes" euler="0 0 {geom_deg}"/>
      </body>
    </body>
    <body name="robot"><freejoint/><geom size="0.01"/></body>
  </worldbody>
</mujoco>"""


@pytest.mark.parametrize('body_deg, geom_deg', [(0, 0), (90, 0), (0, 180), (180, 90), (-90, 0)])
def test_hfield_in_a_body_fixed_to_the_world_turned_by_quarter_turns(body_deg, geom_deg):
    """The hfield of a (nested) static body, turned about z by multiples of 90 deg in all:
    its heights at each world point are the unturned field's at the point's place in the
    geom's frame, and MuJoCo's own ray casts agree (exactly at the nodes)."""
    model = mujoco.MjModel.from_xml_string(HFIELD_IN_A_BODY.format(body_deg=body_deg,
                                                                    geom_deg=geom_deg))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    grid = HeightGrid.from_mjcf_hfield(model)  # the only hfield geom
    assert grid.notices == ()  # (a quarter turn's rounding is no turn to tell)
    g = model.geom('terrain').id
    rotation, pos = data.geom_xmat[g].reshape(3, 3), data.geom_xpos[g]
    flat = HeightGrid.from_mjcf_hfield(mujoco.MjModel.from_xml_string(HFIELD), 'terrain')
    rng = np.random.default_rng(1)
    local = rng.uniform([-0.6, -0.4], [0.6, 0.4], size=(50, 2))
    world = pos[:2] + local @ rotation[:2, :2].T
    # the same field (HFIELD's geom sits at 0.1, -0.2, 0.02: shift to its frame)
    expected = flat.height(local[:, 0] + 0.1, local[:, 1] - 0.2) - 0.02 + pos[2]
    assert np.allclose(grid.height(world[:, 0], world[:, 1]), expected, rtol=0, atol=1e-12)
    geomid = np.zeros(1, dtype=np.int32)
    for i in range(4):
        for j in range(3):
            node = pos[:2] + rotation[:2, :2] @ [-0.6 + 0.4 * i, -0.4 + 0.4 * j]
            inside = pos[:2] + 0.999 * (node - pos[:2])  # (a ray exactly on the edge misses)
            distance = mujoco.mj_ray(model, data, np.array([*inside, 1.0]),
                                     np.array([0, 0, -1.0]), None, 1, -1, geomid)
            assert geomid[0] == g
            assert 1.0 - distance == pytest.approx(grid.height(*inside), abs=2e-3)


def test_hfield_geoms_that_cannot_be_read_are_refused_with_the_reason():
    def model(xml):
        return mujoco.MjModel.from_xml_string(xml)
    tilted = HFIELD_IN_A_BODY.format(body_deg=0, geom_deg=0).replace(
        'euler="0 0 0"/>', 'euler="5 0 0"/>')
    with pytest.raises(ValueError, match="hfield geom 'terrain' is tilted 5 deg"):
        HeightGrid.from_mjcf_hfield(model(tilted), 'terrain')
    moving = HFIELD_IN_A_BODY.format(body_deg=0, geom_deg=0).replace(
        '<body name="ground" pos="0.3 0.1 0.0" euler="0 0 0">',
        '<body name="ground" pos="0.3 0.1 0.0" euler="0 0 0"><joint type="slide"/>')
    with pytest.raises(ValueError, match='must be fixed to the world'):
        HeightGrid.from_mjcf_hfield(model(moving))
    mocap = HFIELD.replace('<worldbody><geom', '<worldbody><body mocap="true"><geom').replace(
        '</worldbody>', '</body></worldbody>')
    with pytest.raises(ValueError, match='must be fixed to the world'):
        HeightGrid.from_mjcf_hfield(model(mocap))
    two = HFIELD.replace('</worldbody>', '<geom name="second" type="hfield" hfield="dunes" '
                         'pos="3 0 0"/></worldbody>')
    with pytest.raises(ValueError, match=r'name the hfield geom to read; the model has 2 '
                                         r'\(terrain, second\)'):
        HeightGrid.from_mjcf_hfield(model(two))
    assert HeightGrid.from_mjcf_hfield(model(two), 'second').center == (3.0, 0.0)
    with pytest.raises(ValueError, match="reads the model's own <hfield> geom; the model "
                                         'has none'):
        HeightGrid.from_mjcf_hfield(model('<mujoco/>'))


UNNAMED_HFIELDS = """
<mujoco>
  <asset><hfield name="dunes" nrow="3" ncol="4" size="0.6 0.4 0.05 0.01"
                 elevation="0 1 2 3  1 2 3 4  0 0 4 4"/>
         <hfield name="ramp" nrow="2" ncol="2" size="0.5 0.5 0.1 0.01" elevation="0 1 0 1"/>
  </asset>
  <worldbody>
    <geom type="hfield" hfield="dunes" pos="5 0 0"/><geom type="hfield" hfield="dunes"/>
    <geom type="hfield" hfield="ramp" pos="0 3 0"/><geom name="ball" size="0.1"/>
  </worldbody>
</mujoco>"""


def test_unnamed_hfield_geoms_are_named_by_their_hfield_or_their_id():
    """Terrain generators name the <hfield> asset but not its geom: such a geom is taken by
    its asset's name, or, when several geoms share the asset, by its id; errors list the
    hfield geoms in the form that is taken back."""
    model = mujoco.MjModel.from_xml_string(UNNAMED_HFIELDS)
    with pytest.raises(ValueError, match=r'the model has 3 \(0, 1, ramp\)'):
        HeightGrid.from_mjcf_hfield(model)
    assert HeightGrid.from_mjcf_hfield(model, 'ramp').center == (0.0, 3.0)
    assert HeightGrid.from_mjcf_hfield(model, '0').center == (5.0, 0.0)
    assert HeightGrid.from_mjcf_hfield(model, 1).center == (0.0, 0.0)
    with pytest.raises(ValueError, match="2 geoms use <hfield> 'dunes'; its hfield geoms: "
                                         '0, 1, ramp'):
        HeightGrid.from_mjcf_hfield(model, 'dunes')
    with pytest.raises(ValueError, match="no geom or <hfield> 'dune' in the model"):
        HeightGrid.from_mjcf_hfield(model, 'dune')
    with pytest.raises(ValueError, match="geom 'ball' is not an hfield geom; the model's: "
                                         '0, 1, ramp'):
        HeightGrid.from_mjcf_hfield(model, 'ball')
    # the scene key takes an id as YAML gives it (an integer)
    scene = load_scene('plate_drop', {'sand.surface.type': 'hfield', 'sand.surface.geom': 0,
                                      'duration': 0.01})
    assert scene.surface['geom'] == '0'


TURNED_RAMP = """
<mujoco>
  <asset><hfield name="{name}" nrow="{rows}" ncol="{cols}" size="0.6 0.4 0.08 0.01"
                 elevation="{elevation}"/></asset>
  <worldbody><geom type="hfield" hfield="{name}" pos="0.2 -0.1 0.03" euler="0 0 {deg}"/>
  </worldbody>
</mujoco>"""


def _turned_field(name, values, deg):
    """TURNED_RAMP's model with the hfield data `values` (9 x 13, 0..1) turned `deg`."""
    rows, cols = values.shape
    return mujoco.MjModel.from_xml_string(TURNED_RAMP.format(
        name=name, rows=rows, cols=cols, deg=deg,
        elevation=' '.join(f'{h:.17g}' for h in values.ravel())))


def _ray_heights(model, points):
    """MuJoCo's own height of the ground under each world (x, y) (ray casts from z = 1 m)."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geomid = np.zeros(1, dtype=np.int32)
    heights = []
    for x, y in points:
        distance = mujoco.mj_ray(model, data, np.array([x, y, 1.0]), np.array([0, 0, -1.0]),
                                 None, 1, -1, geomid)
        assert geomid[0] == 0
        heights.append(1.0 - distance)
    return np.array(heights)


def _turn(deg, local):
    """World (x, y) of points `local` ((n, 2), m) in TURNED_RAMP's geom frame, turned deg."""
    turn = np.radians(deg)
    return np.array([0.2, -0.1]) + local @ np.array([[np.cos(turn), -np.sin(turn)],
                                                     [np.sin(turn), np.cos(turn)]]).T


#: TURNED_RAMP's field: 13 x 9 nodes 0.1 m apart, heights 0 .. 0.08 m.
RAMP_VALUES = 0.5 + 0.3 * np.linspace(-1, 1, 13)[None, :] - 0.2 * np.linspace(-1, 1, 9)[:, None]
BUMPS = np.random.default_rng(5).uniform(0.0, 1.0, (9, 13))
FIELD_NODES = np.array([[-0.6 + 0.1 * i, -0.4 + 0.1 * j] for j in range(9) for i in range(13)])


@pytest.mark.parametrize('deg', [30.0, 135.0, -60.0])
def test_hfield_turned_by_any_angle_is_resampled_onto_the_world_grid(deg):
    """An hfield turned about z by an angle that is not (near) a quarter turn is resampled
    at a quarter of its node spacing onto a world-aligned grid: a ramp (heights linear in
    the geom's x, y) is read as it is up to a resampled cell (25 mm) from its edge, where
    bilinear interpolation of a linear field is that field; a bumpy field agrees with
    MuJoCo's own ray casts within a cell's node range, and at the field's own nodes within
    15 % of its relief (a node's peak falls between the resampled nodes); the grid says so
    in a notice."""
    grid = HeightGrid.from_mjcf_hfield(_turned_field('ramp', RAMP_VALUES, deg))
    assert len(grid.notices) == 1 and f'turned {deg:.6g} deg about z' in grid.notices[0]
    assert '25 mm apart (1/4 of its node spacing' in grid.notices[0]
    unturned = HeightGrid.from_mjcf_hfield(_turned_field('ramp', RAMP_VALUES, 0.0))
    local = np.random.default_rng(4).uniform([-0.56, -0.36], [0.56, 0.36], size=(400, 2))
    world = _turn(deg, local)
    expected = unturned.height(0.2 + local[:, 0], -0.1 + local[:, 1])
    assert np.ptp(expected) > 0.04  # (a ramp, not a level)
    # (linear to MuJoCo's float32 storage of the data: 1e-9 m here)
    assert np.allclose(grid.height(world[:, 0], world[:, 1]), expected, rtol=0, atol=1e-8)
    model = _turned_field('bumps', BUMPS, deg)
    grid = HeightGrid.from_mjcf_hfield(model, 'bumps')
    assert np.all(np.abs(_ray_heights(model, world[:40]) - grid.height(*world[:40].T)) < 0.08)
    inner = FIELD_NODES[(np.abs(FIELD_NODES[:, 0]) < 0.55) & (np.abs(FIELD_NODES[:, 1]) < 0.35)]
    nodes = _turn(deg, inner)
    assert np.max(np.abs(_ray_heights(model, nodes) - grid.height(*nodes.T))) < 0.15 * 0.08


def test_hfield_turned_within_a_tenth_of_a_node_spacing_of_a_quarter_turn_is_read_as_it():
    """A generator's euler -1.57 (-89.954 deg) is read as -90 deg, exactly, as the notice
    says: the field's nodes move under a tenth of their spacing (0.58 mm here), far less than
    resampling would smooth it; so the sand agrees with MuJoCo's own ray casts at the field's
    nodes to that move times the field's slope."""
    model = _turned_field('bumps', BUMPS, -89.954)
    grid = HeightGrid.from_mjcf_hfield(model)
    assert grid.notices == ("hfield geom 'bumps' is turned -89.954 deg about z: read as -90 "
                            'deg, exactly (its nodes move at most 0.58 mm, 0.0058 of its node '
                            'spacing)',)
    exact = HeightGrid.from_mjcf_hfield(_turned_field('bumps', BUMPS, -90.0))
    assert np.array_equal(grid.grid, exact.grid) and grid.origin == exact.origin
    assert exact.notices == ()
    # the same with a plane around it (the snap is decided on the field, not its ring)
    beyond = HeightGrid.from_mjcf_hfield(model, beyond=0.0)
    assert beyond.notices == grid.notices and beyond.grid.shape == (15, 11)
    steepest = np.tan(np.radians(grid.steepest_deg()))
    inner = FIELD_NODES[(np.abs(FIELD_NODES[:, 0]) < 0.55) & (np.abs(FIELD_NODES[:, 1]) < 0.35)]
    nodes = _turn(-89.954, inner)
    assert np.max(np.abs(_ray_heights(model, nodes) - grid.height(*nodes.T))) < \
        0.58e-3 * steepest * 1.01


@pytest.mark.parametrize('deg', [45.0, -89.954])
def test_a_turned_hfield_within_the_plane_is_the_plane_a_cell_beyond_its_edges(deg):
    """`beyond: plane` around a turned hfield: the plane at sand.surface_height from one field
    cell (0.1 m) and one resampled cell (25 mm) outside the field's own turned edges on, also
    at the corners of its world-aligned bounding box; the field itself inside."""
    model = _turned_field('ramp', RAMP_VALUES, deg)
    patch = surface_from_settings({'type': 'hfield', 'beyond': 'plane'}, -0.2, model)
    edge = surface_from_settings({'type': 'hfield'}, -0.2, model)
    ring = np.random.default_rng(8).uniform(-1.0, 1.0, (4000, 2))
    outside = ring[(np.abs(ring[:, 0]) > 0.6 + 0.1 + 0.036) | (np.abs(ring[:, 1]) > 0.4 + 0.136)]
    assert np.allclose(patch.height(*_turn(deg, outside).T), -0.2, rtol=0, atol=1e-15)
    inside = ring[(np.abs(ring[:, 0]) < 0.56) & (np.abs(ring[:, 1]) < 0.36)]
    assert np.allclose(patch.height(*_turn(deg, inside).T), edge.height(*_turn(deg, inside).T),
                       rtol=0, atol=1e-8)


def test_grid_files_png_and_npy(tmp_path):
    from matplotlib.image import imsave
    heights = np.linspace(0, 1, 12).reshape(3, 4)
    np.save(tmp_path / 'h.npy', heights)
    grid = surface_from_settings({'type': 'grid', 'file': str(tmp_path / 'h.npy'),
                                  'size': [0.3, 0.2]}, base_height=0.5)
    assert grid.height(-0.15, -0.1) == pytest.approx(0.5)
    assert grid.height(0.15, 0.1) == pytest.approx(1.5)
    image = np.zeros((3, 4))
    image[0, :] = 1.0  # top image row: the +y edge
    imsave(tmp_path / 'h.png', image, cmap='gray', vmin=0, vmax=1)
    png = surface_from_settings({'type': 'grid', 'file': str(tmp_path / 'h.png'),
                                 'size': [0.3, 0.2], 'height_range': [0.0, 0.04]})
    assert png.height(0.0, 0.1) == pytest.approx(0.04, abs=1e-3)
    assert png.height(0.0, -0.1) == pytest.approx(0.0, abs=1e-3)
    with pytest.raises(ValueError, match='height_range'):
        surface_from_settings({'type': 'grid', 'file': str(tmp_path / 'h.png'),
                               'size': [0.3, 0.2]})
    with pytest.raises(ValueError, match='not found'):
        surface_from_settings({'type': 'grid', 'file': 'nothing.npy', 'size': [1, 1]})
    with pytest.raises(ValueError, match='type'):
        surface_from_settings({'type': 'dune'})


def test_a_field_within_the_plane_beyond_it(tmp_path):
    """`beyond: plane`: the field's own heights over it (to rounding); the plane at
    sand.surface_height from one cell outside it on (its edge continued by default); and an
    hfield of the model likewise, around its turned bounding box."""
    heights = np.random.default_rng(6).uniform(0.0, 0.05, (5, 7))
    np.save(tmp_path / 'h.npy', heights)
    settings = {'type': 'grid', 'file': str(tmp_path / 'h.npy'), 'size': [0.6, 0.4],
                'center': [1.0, -0.5]}
    edge = surface_from_settings(settings, base_height=0.2)
    patch = surface_from_settings({**settings, 'beyond': 'plane'}, base_height=0.2)
    rng = np.random.default_rng(7)
    x, y = rng.uniform(0.7, 1.3, 50), rng.uniform(-0.7, -0.3, 50)
    assert np.allclose(patch.height(x, y), edge.height(x, y), rtol=0, atol=1e-14)
    far = np.array([[-3.0, 0.0], [1.0, 2.0], [1.41, -0.5], [1.0, -0.81]])  # (a cell: 0.1 m)
    assert np.all(patch.height(far[:, 0], far[:, 1]) == 0.2)
    assert not np.any(edge.height(far[:, 0], far[:, 1]) == 0.2)
    assert 0.2 <= patch.height(1.35, -0.5) <= 0.2 + heights[:, -1].max()  # the one-cell rim
    with pytest.raises(ValueError, match="beyond must be 'edge' or 'plane'"):
        surface_from_settings({**settings, 'beyond': 'wall'})
    model = mujoco.MjModel.from_xml_string(HFIELD)
    hfield = surface_from_settings({'type': 'hfield', 'beyond': 'plane'}, -0.3, model)
    assert hfield.height(5.0, 5.0) == -0.3
    assert hfield.height(0.1, -0.2) == pytest.approx(surface_from_settings(
        {'type': 'hfield'}, -0.3, model).height(0.1, -0.2), abs=1e-14)


def test_zeta_map_multiplies_zeta_where_the_plates_are():
    patch = ZetaMap.from_regions([{'x': [-2, 2], 'y': [-2, 2], 'factor': 0.25}])
    elsewhere = ZetaMap.from_regions([{'x': [5, 6], 'y': [5, 6], 'factor': 0.25}])
    *_, plain = _wrenches(Plane(0.0), 0)
    *_, soft = _wrenches(Plane(0.0), 0, zeta_map=patch)
    *_, away = _wrenches(Plane(0.0), 0, zeta_map=elsewhere)
    assert np.abs(plain).max() > 0
    assert np.allclose(soft, 0.25 * plain, rtol=1e-12)
    assert np.array_equal(away, plain)
    half = ZetaMap.from_regions([{'x': [0, 1], 'y': [-1, 1], 'factor': 3.0},
                                 {'x': [0.5, 1], 'y': [-1, 1], 'factor': 0.5}], cell=0.1)
    assert np.allclose(half.factor([-0.5, 0.25, 0.75, 2.0], 0.0), [1.0, 3.0, 0.5, 1.0])
    with pytest.raises(ValueError, match='regions'):
        zeta_map_from_settings({'regions': [{'x': [1, 0], 'y': [0, 1], 'factor': 2}]})
    with pytest.raises(ValueError, match=r'regions\[0\]: factor must be finite and > 0, got nan'):
        zeta_map_from_settings({'regions': [{'x': [0, 1], 'y': [0, 1], 'factor': np.nan}]})
    with pytest.raises(ValueError, match=r'regions\[1\] \(x 0.5 .. 0.504, y -0.5 .. 0 m\) holds no '
                                         'cell centre of the 0.01 m cells'):  # (it vanished)
        ZetaMap.from_regions([{'x': [0, 1], 'y': [-1, 1], 'factor': 3.0},
                              {'x': [0.5, 0.504], 'y': [-0.5, 0], 'factor': 0.1}])
    with pytest.raises(ValueError, match=r"sand.zeta_map: the regions' raster \(0.01 m cells\) "
                                         r'of 200000000 x 200000000 cells needs about 8.94e\+08 '
                                         'GiB, more than half'):  # (before any allocation)
        ZetaMap.from_regions([{'x': [-1e6, 1e6], 'y': [-1e6, 1e6], 'factor': 0.5}])
    engine = Simulation(load_scene('plate_drop', {'sand.zeta_map.regions': [
        {'x': [-1, 1], 'y': [-1, 1], 'factor': 8.0}]})).engine
    assert engine.zeta_at([0.0, 2.0], 0.0).tolist() == [30.0, 3.75]
    from rft_sim_ros.sand.timestep import timestep_problem
    assert "at zeta 3.75 N/cm^3 x the zeta map's largest factor 8;" in timestep_problem(
        engine, 0.01, 3.75)


def test_zeta_map_from_a_file(tmp_path):
    np.save(tmp_path / 'z.npy', np.array([[1.0, 2.0], [3.0, 4.0]]))
    zmap = zeta_map_from_settings({'file': str(tmp_path / 'z.npy'), 'size': [2.0, 2.0]})
    assert np.allclose(zmap.factor([-0.5, 0.5, -0.5, 0.5], [-0.5, -0.5, 0.5, 0.5]),
                       [1, 2, 3, 4])
    np.save(tmp_path / 'z3.npy', np.ones((2, 2, 2)))
    with pytest.raises(ValueError, match=r'a zeta map is a 2-D array of factors \[rows \(y\), '
                                         r'columns \(x\)\], got 3 dimension'):
        zeta_map_from_settings({'file': str(tmp_path / 'z3.npy'), 'size': [2.0, 2.0]})


def test_scene_keys_select_the_surface_and_bad_ones_are_refused(tmp_path):
    np.save(tmp_path / 'flat.npy', np.zeros((5, 5)))
    scene = load_scene('plate_drop', {'sand.surface.type': 'grid',
                                      'sand.surface.file': str(tmp_path / 'flat.npy'),
                                      'sand.surface.size': [1.0, 1.0], 'duration': 0.01})
    assert isinstance(Simulation(scene).engine.surface, HeightGrid)
    with pytest.raises(SceneError, match='angle_deg: must be <= 89.9'):
        load_scene('plate_drop', {'sand.surface.type': 'slope', 'sand.surface.angle_deg': 100})
    with pytest.raises(SceneError, match='sand.surface: must be a mapping'):
        load_scene('plate_drop', {'sand.surface': 3})
    with pytest.raises(SceneError, match='sand.surface.type: must be one of'):
        load_scene('plate_drop', {'sand.surface.type': 'dune'})
    scene = load_scene('plate_drop', {'sand.surface.type': 'grid', 'duration': 0.01})
    with pytest.raises(SceneError, match='needs sand.surface.file'):
        Simulation(scene)
    scene = load_scene('plate_drop', {'sand.surface.type': 'hfield', 'duration': 0.01,
                                      'sand.surface.geom': 'plate_geom'})
    with pytest.raises(SceneError, match='not an hfield geom'):
        Simulation(scene)
    with pytest.raises(SceneError, match=r"sand.surface.geom: must be a geom's name or its id "
                                         r'\(an integer >= 0\), got -1'):
        load_scene('plate_drop', {'sand.surface.type': 'hfield', 'sand.surface.geom': -1})
    np.save(tmp_path / 'rgb.npy', np.zeros((5, 5, 3)))
    scene = load_scene('plate_drop', {'sand.surface.type': 'grid', 'sand.surface.size': [1, 1],
                                      'sand.surface.file': str(tmp_path / 'rgb.npy')})
    with pytest.raises(SceneError, match=r'a height grid is a 2-D array of heights \[rows \(y\), '
                                         r'columns \(x\)\], got 3 dimension\(s\), shape '):
        Simulation(scene)


def _drop(overrides, duration=1.5):
    sim = Simulation(load_scene('plate_drop', {'duration': duration, **overrides}))
    sim.step(int(round(duration / sim.timestep)))
    return sim


def test_plate_drop_on_a_flat_height_grid_is_the_plane_drop_at_that_height(tmp_path):
    h = 0.05
    np.save(tmp_path / 'flat.npy', np.zeros((9, 9)))
    plane = _drop({'sand.surface_height': h}, duration=0.3)
    grid = _drop({'sand.surface_height': h, 'sand.surface.type': 'grid',
                  'sand.surface.file': str(tmp_path / 'flat.npy'),
                  'sand.surface.size': [2.0, 2.0]}, duration=0.3)
    assert np.array_equal(plane.data.qpos, grid.data.qpos)
    assert np.array_equal(plane.data.qvel, grid.data.qvel)
    # the grid's own heights at h (sand.surface_height 0): the plate starts above it and its
    # depths are measured from it, as on the plane at h
    np.save(tmp_path / 'raised.npy', np.full((9, 9), h))
    raised = _drop({'sand.surface.type': 'grid', 'sand.surface.file': str(tmp_path / 'raised.npy'),
                    'sand.surface.size': [2.0, 2.0]}, duration=0.3)
    assert np.array_equal(plane.data.qpos, raised.data.qpos)
    assert raised.scenario.metrics(raised) == plane.scenario.metrics(plane)


def test_plate_press_on_a_raised_grid_and_on_a_slope_feels_zeta_a_per_depth(tmp_path):
    """plate_press starts above the surface under the plate, whatever its shape: on a grid
    raised 5 cm it is the plane's press at 5 cm; on a 10 and a 30 deg slope a horizontal
    plate's force is still zeta A times the depth at its centre once it is wholly in (depth
    linear across), which the fit then holds to rounding; a press that never takes the plate
    wholly in (30 deg: 2.9 cm of the 10 cm plate's rise) has no force per depth to report."""
    def press(overrides):
        sim = Simulation(load_scene('plate_press', overrides))
        sim.step(int(round(sim.scene.duration / sim.timestep)))
        return sim.scenario.metrics(sim)
    np.save(tmp_path / 'raised.npy', np.full((9, 9), 0.05))
    plane = press({'sand.surface_height': 0.05})
    raised = press({'sand.surface.type': 'grid', 'sand.surface.file': str(tmp_path / 'raised.npy'),
                    'sand.surface.size': [2.0, 2.0]})
    assert raised == pytest.approx(plane, rel=1e-12, abs=1e-12)  # (the slide offset rounds)
    slope = press({'sand.surface.type': 'slope', 'sand.surface.angle_deg': 10.0})
    assert abs(slope['force_per_sinkage_error']) < 1e-9
    assert slope['max_sinkage_m'] == pytest.approx(plane['max_sinkage_m'], rel=1e-3)
    steep = {'sand.surface.type': 'slope', 'sand.surface.angle_deg': 30.0}
    assert press(steep)['force_per_sinkage_error'] is None  # (2.5 cm deep: not wholly in)
    assert abs(press({**steep, 'duration': 6.0})['force_per_sinkage_error']) < 1e-9


def test_plate_drop_on_a_slope_has_no_energy_balance_to_hold():
    """The impact depth's energy balance assumes sand level under the plate: on a slope the
    expected impact depth and its error are None (not a false error), the static depth
    stays."""
    sim = Simulation(load_scene('plate_drop', {'sand.surface.type': 'slope',
                                               'sand.surface.angle_deg': 10.0,
                                               'duration': 0.3}))
    sim.step(int(round(sim.scene.duration / sim.timestep)))
    metrics = sim.scenario.metrics(sim)
    assert metrics['expected_max_sinkage_m'] is None and metrics['max_sinkage_error'] is None
    assert metrics['static_sinkage_m'] == pytest.approx(1.0 * 9.81 / (3.75e6 * 0.01), rel=1e-3)


@pytest.mark.parametrize('angle', [10.0, 20.0])
def test_plate_dropped_on_a_slope_comes_to_rest(angle):
    """A 1 kg plate on a slope gentler than the sand's angle of repose (~30 deg) sinks in and
    is held: rest speed < 1 mm/s, no creep down the slope."""
    sim = _drop({'sand.surface.type': 'slope', 'sand.surface.angle_deg': angle,
                 'sand.surface.downhill_deg': 0.0})
    x0 = sim.data.qpos[0]
    sim.step(500)
    speed = np.linalg.norm(sim.data.qvel[:3])
    assert speed < 1e-3
    assert abs(sim.data.qpos[0] - x0) < 1e-3 * 0.5  # < 1 mm/s over 0.5 s


def test_hexapod_standing_on_a_slope_holds_still():
    """Stability-suite case on a 10 deg slope (gentler than the stated limit, the angle of
    repose): the standing hexapod comes to rest and does not creep downhill."""
    sim = Simulation(load_scene('hexapod', {'gait': 'none', 'rft.plates_per_body': 150,
                                            'sand.surface.type': 'slope',
                                            'sand.surface.angle_deg': 10.0}))
    sim.step(int(round(2.0 / sim.timestep)))
    start = sim.data.qpos[:3].copy()
    sim.step(int(round(1.0 / sim.timestep)))
    assert np.linalg.norm(sim.data.qvel[:3]) < 1e-3
    assert np.linalg.norm(sim.data.qpos[:3] - start) < 1e-3  # < 1 mm/s of creep


def test_files_named_on_the_command_line_in_a_study_or_a_node_parameter_are_read_from_there(
        tmp_path, monkeypatch):
    """A relative sand.surface.file (or zeta map, model, scenario file, package folder) given
    with --set is read from the working directory, in a study from the study file's folder,
    in the node's scene_overrides from its working directory; in a scene file from that file's
    folder; a missing one is refused naming where it was looked for."""
    from rft_sim_ros.cli import main
    from rft_sim_ros.resources import config_dir
    from rft_sim_ros.ros.robot_source import scene_overrides
    from rft_sim_ros.scenes.config import anchor_paths
    from rft_sim_ros.study import study_from_mapping
    here, there = tmp_path / 'here', tmp_path / 'there'
    here.mkdir(), there.mkdir()
    np.save(here / 'raised.npy', np.full((5, 5), 0.02))
    np.save(there / 'lowered.npy', np.full((5, 5), -0.02))
    np.save(there / 'factors.npy', np.full((5, 5), 0.5))
    grid = {'sand.surface.type': 'grid', 'sand.surface.size': [1.0, 1.0], 'duration': 0.05}
    monkeypatch.chdir(here)
    assert main(['run', 'plate_drop', '--set', 'sand.surface.type=grid', '--set',
                 'sand.surface.file=raised.npy', '--set', 'sand.surface.size=[1, 1]',
                 '--duration', '0.05', '--no-bag', '--quiet', '--out', str(tmp_path / 'run')]) == 0
    assert scene_overrides(['sand.surface.file=raised.npy'])['sand.surface.file'] == \
        str(here / 'raised.npy')
    study = study_from_mapping({'scene': 'plate_drop', 'set': grid,
                                'vary': {'sand.surface.file': ['lowered.npy']},
                                'metrics': ['max_sinkage_m']}, base=there)
    assert study.runs[0].overrides['sand.surface.file'] == str(there / 'lowered.npy')
    assert study.runs[0].varied == {'sand.surface.file': 'lowered.npy'}  # as the user wrote it
    sim = Simulation(load_scene('plate_drop', study.runs[0].overrides))
    assert sim.engine.surface.height(0.0, 0.0) == pytest.approx(-0.02)
    # left as given where not found here: the scene's own look-up (a model in models/)
    assert anchor_paths({'model': 'plate_drop.xml', 'scenario': 'plate_drop',
                         'robot.package_paths': {'a': 'there', 'b': 'nowhere'}}, tmp_path) == {
        'model': 'plate_drop.xml', 'scenario': 'plate_drop',
        'robot.package_paths': {'a': str(there), 'b': 'nowhere'}}
    # a whole mapping that holds a file (a study varying sand.surface) is read from there too
    nested = study_from_mapping({'scene': 'plate_drop', 'set': {'duration': 0.05},
                                 'vary': {'sand.surface': [{'type': 'grid', 'file': 'lowered.npy',
                                                            'size': [1.0, 1.0]}],
                                          'sand': [{'zeta_map': {'file': 'factors.npy',
                                                                 'size': [1.0, 1.0]}}]},
                                 'metrics': ['max_sinkage_m']}, base=there)
    assert nested.runs[0].overrides['sand.surface']['file'] == str(there / 'lowered.npy')
    assert nested.runs[0].overrides['sand']['zeta_map']['file'] == str(there / 'factors.npy')
    with pytest.raises(SceneError, match=r"sand.surface.file: 'lowered.npy' not found: no file "
                       f'{config_dir() / "lowered.npy"} \\(a relative file is read from the '
                       "scene file's folder; one named with --set or in scene_overrides from "
                       f"the working directory, here {here}; one named in a study from the "
                       "study file's folder"):
        load_scene('plate_drop', {**grid, 'sand.surface.file': 'lowered.npy'})
    with pytest.raises(SceneError, match=f"sand.surface.file: '{there}' is a folder, not a file"):
        load_scene('plate_drop', {**grid, 'sand.surface.file': str(there)})
    scene = tmp_path / 'scene.yaml'  # in a scene file: from its folder, whatever the cwd
    scene.write_text((config_dir() / 'plate_drop.yaml').read_text().replace(
        '  surface_height: 0.0  # m', '  surface: {type: grid, file: there/lowered.npy, '
        'size: [1, 1]}', 1))
    assert Simulation(load_scene(scene)).engine.surface.height(0.0, 0.0) == pytest.approx(-0.02)


def test_a_surface_made_in_python_is_the_sand_and_the_summary_records_it(tmp_path):
    """A HeightGrid of an array given to run_scene (Simulation) is the sand: a flat one at h
    drops the plate exactly as the plane at h does; summary.json's `surface` records it, its
    heights' SHA-256 telling it from another grid; a scene whose own sand.surface is not the
    plane, or anything but a Surface, is refused."""
    heights = np.full((21, 31), 0.03)
    flat = HeightGrid(heights, size=(3.0, 2.0), center=(0.5, 0.0))
    given = run_scene(load_scene('plate_drop', {'duration': 0.3}), tmp_path / 'given',
                      progress=False, plots=False, surface=flat)
    plane = run_scene(load_scene('plate_drop', {'duration': 0.3, 'sand.surface_height': 0.03}),
                      progress=False, plots=False)
    assert given['metrics'] == plane['metrics'] and given['metrics']['max_sinkage_m'] > 0.005
    assert plane['surface'] == {'type': 'plane', 'height_m': 0.03}
    saved = json.loads((tmp_path / 'given' / 'summary.json').read_text())['surface']
    assert saved == {'type': 'grid', **flat.placement(), 'given_in_python': True,
                     'heights_sha256': heights_digest(heights)}
    assert heights_digest(heights + 1e-12) != heights_digest(heights)
    assert heights_digest(heights.reshape(31, 21)) != heights_digest(heights)
    with pytest.raises(SceneError, match="replaces the scene's sand.surface, which is a slope"):
        Simulation(load_scene('plate_drop', {'sand.surface.type': 'slope'}), surface=flat)
    with pytest.raises(SceneError, match=r'surface must be a rft_sim_ros.sand.surface.Surface '
                                         r'\(a Plane, Slope or HeightGrid\), got ndarray'):
        Simulation(load_scene('plate_drop'), surface=heights)
    with pytest.raises(SceneError, match="got DeformableSand; deformable sand is the scene's "
                                         'sand.deformable, laid over the surface given'):
        Simulation(load_scene('plate_drop'), surface=DeformableSand(flat, size=(0.5, 0.5)))
