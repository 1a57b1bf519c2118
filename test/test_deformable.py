"""Deformable sand: craters and piles that conserve volume, avalanches to the angle of repose,
footprints a returning body meets, reset, and rest on deformed sand."""
import mujoco
import numpy as np
import pytest

from rft_sim_ros.sand.deformable import DeformableSand, neighbour_slopes
from rft_sim_ros.sand.deformable_codes import COUNT
from rft_sim_ros.sand.deformable_kernels import _free_distances, mark_cell, settle, touch_cell
from rft_sim_ros.sand.surface import (BLOCK, HeightGrid, Plane, Slope, block_maximum,
                                      block_minimum)
from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.sim.simulation import Simulation
from rft_sim_ros.validation.terrain import lift_out, plate_redrop

BED = {'sand.deformable.enabled': True, 'sand.deformable.size': [0.5, 0.5]}


@pytest.mark.parametrize('repose', [25.0, 34.0])
def test_a_pile_steeper_than_repose_relaxes_to_it_conserving_volume(repose):
    bed = DeformableSand(Plane(0.1), size=(0.6, 0.6), cell=0.01, repose_deg=repose)
    with bed.editing() as heights:
        heights[30, 30] += 0.08  # a column of sand 8 cm tall, one cell wide
        heights[10:14, 40:44] += 0.03
    before = bed.grid.sum()
    moved = 0.08 + 16 * 0.03
    bed.relax_all()
    axis, diagonal = neighbour_slopes(bed.grid, bed.cell)
    limit = np.tan(np.radians(repose))
    assert axis <= limit * (1 + 2e-3) and diagonal <= limit * (1 + 2e-3)
    assert axis > 0.9 * limit  # a pile at (close to) the angle of repose, not flattened
    assert abs(bed.grid.sum() - before) <= 1e-9 * moved
    assert np.array_equal(bed.block_max, block_maximum(bed.grid))
    assert np.array_equal(bed.block_min, block_minimum(bed.grid))
    assert bed.grid.max() < 0.1 + 0.08


def _drop(extra=None, steps=800):
    sim = Simulation(load_scene('plate_drop', {'duration': 2.0, **BED, **(extra or {})}))
    sim.step(steps)
    return sim


def test_a_dropped_plate_leaves_a_crater_whose_volume_is_piled_around_it():
    sim = _drop()
    bed = sim.engine.surface
    rest_speed = np.linalg.norm(sim.data.qvel[:3])
    depth = -(sim.data.qpos[2] - 0.001)  # plate bottom below the pristine surface
    assert rest_speed < 1e-3  # at rest on deformable sand
    before = bed.displaced_volume()  # (edge nodes its side plates mark in turn, only)
    assert bed.state[COUNT] > 100  # its footprint nodes are pending
    lift_out(sim)
    assert bed.state[COUNT] == 0
    crater, pile = bed.displaced_volume(), bed.piled_volume()
    assert before < 0.05 * crater
    assert crater > 0.5 * depth * 0.1 * 0.1  # a 10 x 10 cm footprint about `depth` deep
    assert abs(crater - pile) <= 1e-9 * crater
    assert abs(bed.volume_change()) <= 1e-9 * crater
    assert bed.max_footprint_depth() == pytest.approx(depth, abs=1e-4)
    # the pile rings the crater: sand above the pristine level just outside the plate
    ring = bed.grid[[19, 31], 25]
    assert (ring > 0).all() and bed.grid[25, 25] < 0
    metrics = sim.terrain_metrics()
    assert metrics['sand_volume_change_m3'] == bed.volume_change()
    assert metrics['max_footprint_depth_m'] == bed.max_footprint_depth()


def test_each_plate_in_the_sand_marks_the_four_nodes_of_its_cell():
    """The gather's marks (one per run of plates in a cell) are those of one mark per plate
    in the sand, in plate order: the nodes of its cell pending in order of first mark, each
    remembering the lowest plate z."""
    sim = Simulation(load_scene('plate_drop', BED))
    engine, model, data, bed = sim.engine, sim.model, sim.data, sim.engine.surface
    while bed.state[COUNT] == 0:  # falling until its first step in the sand
        mujoco.mj_step1(model, data)
        xpos, xmat = data.xpos.copy(), data.xmat.copy()
        engine.apply()
        mujoco.mj_step2(model, data)
    ny, nx = bed.grid.shape
    order, lowest = [], {}
    for i, body in enumerate(engine.body_ids):
        local = engine.local_pos[engine.plate_start[i]:engine.plate_start[i + 1]]
        world = local @ xmat[body].reshape(3, 3).T + xpos[body]
        for x, y, z in world[bed.height(world[:, 0], world[:, 1]) > world[:, 2]]:
            u = int((x - bed.origin[0]) * (1.0 / bed.spacing[0]))
            v = int((y - bed.origin[1]) * (1.0 / bed.spacing[1]))
            for node in (v * nx + u, v * nx + u + 1, (v + 1) * nx + u, (v + 1) * nx + u + 1):
                if node not in lowest:
                    order.append(node)
                lowest[node] = min(lowest.get(node, np.inf), z)
    assert len(order) > 100
    pending = bed.pending[:bed.state[COUNT]]
    assert pending.tolist() == order
    assert np.allclose(bed.lowest.ravel()[pending], [lowest[n] for n in order], rtol=0,
                       atol=1e-12)


def test_a_plate_on_the_beds_far_edge_marks_its_last_cell():
    """A plate exactly on the bed's far edge (u = nx - 1), which the gather reads as on the
    bed, marks the last cell's four nodes, as one on its near edge (u = 0) marks the first
    cell's; only a plate beyond the bed is counted outside it."""
    bed = DeformableSand(Plane(0.0), size=(0.1, 0.1), cell=0.05)  # 3 x 3 nodes
    arrays = bed.kernel_arrays()
    footprints = tuple(arrays[name] for name in (
        'deform_stamp', 'deform_lowest', 'deform_pending', 'deform_state', 'deform_cell_stamp',
        'deform_cell_low'))
    touch_cell(footprints, 0, 2.0, 1.0, -0.01)
    assert bed.state[COUNT] == 4 and bed.plates_outside == 0
    assert sorted(bed.pending[:4].tolist()) == [4, 5, 7, 8]  # nodes [1..2, 1..2]
    touch_cell(footprints, 0, 0.0, 0.0, -0.01)
    assert bed.state[COUNT] == 7 and bed.plates_outside == 0
    touch_cell(footprints, 0, 2.0 + 1e-9, 1.0, -0.01)
    assert bed.state[COUNT] == 7 and bed.plates_outside == 1


def _settle(bed, step):
    """Rules 2-4 for the nodes pending before `step` (as the deformable gather kernel ends)."""
    settle(bed._heights, bed._block_max, bed._block_min, bed.stamp, bed.lowest, bed.pending,
           bed.state, bed._committed, bed._amount, bed._queue, bed._in_queue, bed._dirty,
           bed._dirty_list, bed._changed, bed._distance, bed._reached, step, bed.rise)


def test_a_footprint_of_any_width_is_dug_whole():
    """A 22 cm square footprint in 1 mm cells, left at once: its middle, 110 cells from the
    nearest free node, is dug to the plate's depth (the sand goes to the nearest free ring,
    found for the nodes far inside in one pass: `_free_distances`; it kept its sand beyond
    100 cells), and the volume stays the bed's (the rim's avalanche starts at the edge)."""
    bed = DeformableSand(Plane(0.0), size=(0.3, 0.3), cell=0.001)
    footprints = tuple(bed.kernel_arrays()[name] for name in (
        'deform_stamp', 'deform_lowest', 'deform_pending', 'deform_state', 'deform_cell_stamp',
        'deform_cell_low'))
    for j in range(40, 260):
        for i in range(40, 260):
            mark_cell(footprints, 0, i, j, -0.01)
    _settle(bed, 1)  # no plate marked in step 1: the footprint is left
    assert bed.grid[150, 150] == -0.01 and bed.grid[100:200, 100:200].max() == -0.01
    assert abs(bed.volume_change()) <= 1e-9 * bed.displaced_volume()
    assert bed.piled_volume() == pytest.approx(bed.displaced_volume(), rel=1e-9)
    assert (bed._distance == -1).all()  # (set back for the next step)


def test_the_distance_to_the_nearest_free_node_is_chebyshevs():
    """`_free_distances` against the brute-force Chebyshev distance from every node under a
    body (pending or just committed) to the nearest free node, on random beds."""
    rng = np.random.default_rng(7)
    for trial in range(20):
        ny, nx = rng.integers(3, 40, size=2)
        stamp = np.where(rng.random((ny, nx)) < rng.uniform(0.5, 0.97), -2, -1)
        stamp[(stamp == -2) & (rng.random((ny, nx)) < 0.5)] = 3  # some pending, some committed
        pending, committed = np.flatnonzero(stamp >= 0), np.flatnonzero(stamp == -2)
        distance = np.full((ny, nx), -1, dtype=np.int32)
        reached = np.zeros(ny * nx, dtype=np.int64)
        _free_distances(stamp, pending, len(pending), committed, len(committed), distance,
                        reached)
        free = np.argwhere(stamp == -1)
        for j, i in np.argwhere(stamp != -1):
            expected = np.abs(free - [j, i]).max(axis=1).min() if len(free) else -1
            assert distance[j, i] == expected


def _block_nodes(bed, rows, columns):
    """Where the nodes of the blocks [rows[k], columns[k]] of `bed` lie: a bool (ny, nx)."""
    held = np.zeros(bed.grid.shape, dtype=bool)
    for bj, bi in zip(rows, columns):
        held[bj * BLOCK:(bj + 1) * BLOCK + 1, bi * BLOCK:(bi + 1) * BLOCK + 1] = True
    return held


def test_the_blocks_changed_since_an_epoch_hold_every_changed_height_and_lie_around_it():
    """What a terrain publication compares (`blocks_changed_since`, so that it costs what
    changed, not the bed): the crater a plate leaves lies in the blocks changed since the
    epoch before, which lie around the plate, not across the bed; steps that change nothing
    keep the epoch; a reset and a hand edit (`edited`) change every block."""
    sim = _drop({'sand.deformable.size': [1.0, 1.0]})
    bed = sim.engine.surface
    epoch, before = bed.change_epoch, bed.grid.copy()
    lift_out(sim)
    rows, columns = bed.blocks_changed_since(epoch)
    changed = bed.grid != before
    assert changed.sum() > 100 and _block_nodes(bed, rows, columns)[changed].all()
    assert rows.size <= 16 and bed.block_max.size == 13 * 13  # a 10 cm plate, a 1 m bed
    assert bed.blocks_changed_since(bed.change_epoch)[0].size == 0
    settled = bed.change_epoch
    sim.step(100)  # the plate above the sand, the crater settled: nothing changes
    assert bed.change_epoch == settled
    sim.reset()
    assert bed.blocks_changed_since(settled)[0].size == bed.block_max.size
    with bed.editing() as heights:
        heights[50, 50] += 0.02  # a pile made by hand, above its block's maximum
    assert bed.blocks_changed_since(settled + 1)[0].size == bed.block_max.size
    assert bed.block_max.max() == pytest.approx(bed.pristine.max() + 0.02)


def test_a_plate_dropped_again_into_its_footprint_sinks_deeper():
    """The second drop meets the crater floor, so its depth below the pristine surface is
    about the crater's depth plus a fresh impact depth."""
    sim = _drop()
    first = -(sim.data.qpos[2] - 0.001)
    crater = sim.engine.surface
    lift_out(sim)
    floor = -crater.grid[25, 25]
    sim.data.qpos[:7] = (0.0, 0.0, 0.1 + 0.001, 1, 0, 0, 0)  # the same drop height above 0
    sim.data.qvel[:] = 0.0
    sim.step(800)
    second = -(sim.data.qpos[2] - 0.001)
    assert floor > 0.5 * first
    assert second > first + 0.5 * floor
    assert np.linalg.norm(sim.data.qvel[:3]) < 1e-3


def test_reset_restores_the_pristine_surface_exactly():
    sim = _drop({'sand.surface.type': 'slope', 'sand.surface.angle_deg': 5.0})
    bed = sim.engine.surface
    pristine, blocks = bed.pristine.copy(), block_maximum(bed.pristine)
    lift_out(sim)
    assert not np.array_equal(bed.grid, pristine)
    assert not np.array_equal(bed.block_min, block_minimum(pristine))
    sim.reset()
    assert np.array_equal(bed.grid, pristine) and np.array_equal(bed.block_max, blocks)
    assert np.array_equal(bed.block_min, block_minimum(pristine))
    assert bed.state[COUNT] == 0 and (bed.stamp == -1).all()
    assert np.array_equal(pristine, Slope(0.0, 5.0).height(*np.meshgrid(
        bed.origin[0] + bed.cell * np.arange(bed.grid.shape[1]),
        bed.origin[1] + bed.cell * np.arange(bed.grid.shape[0]))))


def test_a_dragged_blade_ploughs_a_trench_and_conserves_volume():
    sim = Simulation(load_scene('blade_drag', {**BED, 'sand.deformable.size': [1.0, 0.6]}))
    sim.step(int(round(1.5 / sim.timestep)))  # 2 cm of the stroke
    bed = sim.engine.surface
    assert bed.displaced_volume() > 0 and bed.piled_volume() > 0
    assert abs(bed.volume_change()) <= 1e-9 * bed.displaced_volume()
    axis, _ = neighbour_slopes(bed.grid, bed.cell)
    assert np.isfinite(axis)


def test_deformable_keys_are_checked():
    with pytest.raises(SceneError, match='sand.deformable.enabled: must be true or false'):
        load_scene('plate_drop', {'sand.deformable.enabled': 'yes'})
    with pytest.raises(SceneError, match='sand.deformable.cell: must be > 0'):
        load_scene('plate_drop', {'sand.deformable.cell': 0})
    with pytest.raises(ValueError, match='at least two cells'):
        DeformableSand(Plane(), size=(0.01, 1.0), cell=0.01)
    # a bed far larger than any machine's memory is refused before anything is allocated
    with pytest.raises(ValueError, match=r'a bed \(0.01 m cells\) of 1000001 x 1000001 nodes '
                       r'needs about 9.5e\+04 GiB, more than half of this machine'):
        DeformableSand(Plane(), size=(1e4, 1e4), cell=0.01)
    for size, cell in (((1e300, 1e300), 0.01), ((1.0, 1.0), 1e-300)):  # (counted as floats)
        with pytest.raises(ValueError, match=r'needs about inf GiB, more than half'):
            DeformableSand(Plane(), size=size, cell=cell)
    # a bed where float64 coordinates cannot tell its nodes apart
    with pytest.raises(ValueError, match=r'a height grid reaching 1e\+300 m from the world origin '
                       r'with nodes 0.01 m apart: world coordinates \(float64\) do not resolve'):
        DeformableSand(Plane(), size=(1.0, 1.0), cell=0.01, center=(1e300, 0.0))


def test_cells_wider_than_a_sand_body_are_said_at_start_up():
    """plate_drop's plate is 10 cm wide: 12 cm cells would make every footprint at least a
    cell, said with the body's width; 1 cm cells are not."""
    coarse = Simulation(load_scene('plate_drop', {**BED, 'sand.deformable.cell': 0.12}))
    [said] = [n for n in coarse.notices if 'is wider than' in n]
    assert said.startswith('sand.deformable.cell 0.12 m is wider than sand body plate (10 cm): ')
    fine = Simulation(load_scene('plate_drop', BED))
    assert not [n for n in fine.notices if 'is wider than' in n]


def test_deformable_keys_set_while_deformable_sand_is_off_are_said():
    """A study that sets a cell and varies `enabled` leaves the cell without effect on its
    rigid runs: said at start-up (not refused: the same keys act once enabled)."""
    rigid = Simulation(load_scene('plate_drop', {'sand.deformable.cell': 0.02,
                                                 'sand.deformable.size': [1.0, 1.0]}))
    assert ('sand.deformable.cell, sand.deformable.size set, but sand.deformable.enabled is '
            'false: the sand is rigid and they have no effect (sand.deformable.enabled=true '
            'makes it deformable)') in rigid.notices
    for overrides in ({}, {'sand.deformable.enabled': False}, {**BED}):
        assert not [n for n in Simulation(load_scene('plate_drop', overrides)).notices
                    if 'have no effect' in n]


def test_cells_narrower_than_half_the_plate_spacing_are_said_at_start_up():
    """plate_drop's 500 plates on its 10 x 10 cm plate's faces lie about 9 mm apart: at 2 mm
    cells a plate marks the cell under its centre and leaves the cells between unmarked, said
    with the spacing; 1 cm cells are not."""
    fine = Simulation(load_scene('plate_drop', {**BED, 'sand.deformable.cell': 0.002}))
    [said] = [n for n in fine.notices if 'narrower than half' in n]
    side = np.median(np.sqrt(fine.engine.areas))
    assert said.startswith("sand.deformable.cell 0.002 m is narrower than half the sand bodies' "
                           f'plate spacing ({side * 1e3:.3g} mm, the median plate): ')
    assert not [n for n in Simulation(load_scene('plate_drop', BED)).notices
                if 'narrower than half' in n]


def test_start_up_says_where_the_bed_lies_and_what_it_rounded():
    """The bed's extent and nodes; a size that is not whole cells rounded (2 m of 3 cm cells:
    67 cells, 2.01 m); a base steeper than the angle of repose said."""
    bed = DeformableSand(Plane(), size=(2.0, 1.2), cell=0.03, center=(0.5, 0.0))
    assert bed.size == pytest.approx((2.01, 1.2)) and bed.grid.shape == (41, 68)
    assert bed.notices == ('deformable bed: x -0.505 .. 1.505 m, y -0.6 .. 0.6 m, 68 x 41 nodes '
                           '0.03 m apart; sand.deformable.size [2.0, 1.2] m rounded to whole '
                           'cells',)
    steep = DeformableSand(Slope(0.0, 35.0), size=(1.0, 1.0), cell=0.05, repose_deg=30.0)
    assert steep.notices[-1] == ('deformable bed: its base surface is steeper (35 deg) than '
                                 'the angle of repose (30 deg): it avalanches wherever the '
                                 'robot disturbs it, and on from there')
    assert len(DeformableSand(Slope(0.0, 25.0), size=(1.0, 1.0), cell=0.05).notices) == 1
    # a pile relaxed to the angle of repose (every neighbour pair within it; its bilinear
    # surface is steeper at some cell corners) is not steeper than repose as a base
    pile = DeformableSand(Plane(0.1), size=(0.6, 0.6), cell=0.01, repose_deg=30.0)
    with pile.editing() as heights:
        heights[30, 30] += 0.08
    pile.relax_all()
    assert pile.steepest_deg() > 31.0
    relaxed = HeightGrid(pile.grid.copy(), pile.size)
    assert len(DeformableSand(relaxed, size=(0.4, 0.4), cell=0.01, repose_deg=30.0).notices) == 1


def test_a_deformable_run_saves_its_final_surface_and_reports_its_volume(tmp_path):
    from rft_sim_ros.sim.runner import run_scene
    summary = run_scene(load_scene('plate_drop', BED), out_dir=tmp_path, duration=0.3,
                        progress=False)
    surface = np.load(tmp_path / 'terrain.npy')
    assert surface.shape == (51, 51) and (tmp_path / 'terrain.png').is_file()
    placed = summary['terrain_grid']  # where the saved nodes lie
    bed = load_scene('plate_drop', BED).values
    assert placed['nodes_xy'] == [51, 51]
    np.testing.assert_allclose(np.array(placed['origin_m']) + 50 * np.array(placed['spacing_m']),
                               -np.array(placed['origin_m']), atol=1e-12)  # centred
    assert placed['spacing_m'][0] == pytest.approx(bed['sand.deformable.size'][0] / 50)
    assert summary['scene_values']['sand.deformable.enabled'] is True
    metrics = summary['metrics']
    assert abs(metrics['sand_volume_change_m3']) < 1e-15
    assert metrics['max_footprint_depth_m'] >= 0.0
    # the plate rests in the sand: its nodes wait for it to leave (no crater yet), said
    assert metrics['sand_nodes_under_bodies'] > 100 and metrics['sand_displaced_m3'] == 0.0
    rigid = run_scene(load_scene('plate_drop'), out_dir=tmp_path / 'rigid', duration=0.05,
                      progress=False)
    assert 'sand_volume_change_m3' not in rigid['metrics']
    assert not (tmp_path / 'rigid' / 'terrain.npy').exists()
    assert metrics['plates_in_sand_outside_bed'] == 0
    assert not any('outside the deformable bed' in notice for notice in summary['notices'])


def test_plates_in_the_sand_outside_the_bed_are_counted_and_warned_about_once(tmp_path):
    """A bed smaller than the plate (0.06 m against 0.1 m): the plate's rim is in the sand
    outside it, leaves no footprint there, and the run says so once, with what to change."""
    from rft_sim_ros.sim.runner import run_scene
    lines = []
    small = {'sand.deformable.enabled': True, 'sand.deformable.size': [0.06, 0.06]}
    summary = run_scene(load_scene('plate_drop', small), out_dir=tmp_path, duration=0.3,
                        progress=False, log=lines.append)
    assert summary['metrics']['plates_in_sand_outside_bed'] > 0
    warned = [line for line in lines if 'outside the deformable bed' in line]
    assert len(warned) == 1 and 'x -0.03 .. 0.03 m' in warned[0]
    assert 'sand.deformable.size' in warned[0] and warned[0] in [
        f'warning: {notice}' for notice in summary['notices']]


BOX_AWAY = """
<mujoco model="box_away">
  <worldbody>
    <body name="box" pos="3.004 -1.996 0.3">
      <freejoint/>
      <geom type="box" size="0.05 0.05 0.02" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_the_bed_lies_under_the_robot_unless_the_scene_places_it(tmp_path):
    """A robot file whose body stands at (3.004, -1.996): the bed is centred under it (to
    whole cells) and it leaves its footprint there; `center` given, the bed is there."""
    model = tmp_path / 'box_away.xml'
    model.write_text(BOX_AWAY)
    bed = {'sand.deformable.enabled': True, 'rft.plates_per_body': 200}
    sim = Simulation(load_scene(model, bed))
    sand = sim.engine.surface
    assert sand.center == pytest.approx((3.0, -2.0), abs=1e-12)
    sim.step(200)
    assert not sand.plates_outside
    assert (sand.stamp >= 0).sum() > 100  # the nodes of its footprint, marked in the bed
    placed = Simulation(load_scene(model, {**bed, 'sand.deformable.center': [0.0, 0.0]}))
    assert placed.engine.surface.center == (0.0, 0.0)
    placed.step(50)
    assert 'outside the deformable bed' in '\n'.join(placed.run_warnings())


@pytest.mark.slow
def test_terrain_study_runs_and_reports(tmp_path):
    from rft_sim_ros.validation.terrain import run_terrain
    results = run_terrain(tmp_path, quick=True, log=lambda line: None)
    report = (tmp_path / 'terrain.md').read_text()
    assert 'Slopes' in report and 'Step cost' in report
    assert abs(results['deformation_hexapod']['deformable']['sand_volume_change_m3']) < 1e-12


def test_the_terrain_study_drops_a_plate_twice_into_its_crater():
    rows = plate_redrop()
    rigid, soft = rows['rigid'], rows['deformable']
    assert rigid['second_depth_m'] == rigid['first_depth_m'] and rigid['crater_floor_m'] == 0
    assert soft['first_depth_m'] == rigid['first_depth_m']  # nothing changes until it leaves
    assert soft['crater_floor_m'] == pytest.approx(soft['first_depth_m'], abs=1e-4)
    # deeper by most of a fresh impact, a little less than a flat-floored crater would give
    assert soft['first_depth_m'] + 0.5 * soft['crater_floor_m'] < soft['second_depth_m']
    assert 0.8 * soft['second_estimate_m'] < soft['second_depth_m'] <= soft['second_estimate_m']
    assert soft['sand_displaced_m3'] == pytest.approx(soft['sand_piled_m3'], rel=1e-9)
    assert abs(soft['sand_volume_change_m3']) <= 1e-9 * soft['sand_displaced_m3']


def test_hexapod_standing_on_deformable_sand_holds_still():
    sim = Simulation(load_scene('hexapod', {'gait': 'none', 'rft.plates_per_body': 150,
                                            **BED}))
    sim.step(int(round(2.0 / sim.timestep)))
    start = sim.data.qpos[:3].copy()
    sim.step(int(round(1.0 / sim.timestep)))
    assert np.linalg.norm(sim.data.qvel[:3]) < 1e-3
    assert np.linalg.norm(sim.data.qpos[:3] - start) < 1e-3
    assert abs(sim.engine.surface.volume_change()) < 1e-15


def test_the_avalanche_works_around_the_changes_not_across_the_space_between_them():
    """Two columns of sand at opposite corners of a 2 m bed relax to the angle of repose in a
    few dozen node visits: the work follows the exchanges, not the 160 x 160 nodes between
    them (one sweep of that box alone would be 25,600 visits)."""
    from rft_sim_ros.sand.deformable_codes import HEAD, MAX_VISITS, QUEUED
    from rft_sim_ros.sand.deformable_kernels import avalanche
    bed = DeformableSand(Plane(0.0), size=(2.0, 2.0), cell=0.01, repose_deg=30.0)
    nx = bed.grid.shape[1]
    heights = bed._heights  # (the kernels' writable heights: the avalanche is called alone)
    for j, i in ((20, 20), (180, 180)):
        heights[j, i] += 0.03
        bed._queue[bed.state[QUEUED]] = j * nx + i  # (as settle queues the nodes it changed)
        bed._in_queue[j, i] = 1
        bed.state[QUEUED] += 1
    assert bed.state[HEAD] == 0
    visits = avalanche(heights, bed.stamp, bed._queue, bed._in_queue, bed.state, bed._dirty,
                       bed._dirty_list, bed.rise, MAX_VISITS)
    assert bed.state[QUEUED] == 0 and visits < 100
    axis, diagonal = neighbour_slopes(bed.grid, bed.cell)
    limit = np.tan(np.radians(30.0))
    assert axis <= limit * (1 + 2e-3) and diagonal <= limit * (1 + 2e-3)
    assert abs(bed.grid.sum() * bed.cell_area - 2 * 0.03 * bed.cell_area) < 1e-15
    assert np.count_nonzero(bed.grid[100:, :100]) == 0  # nothing between them moved
