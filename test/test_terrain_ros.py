"""The sand surface seen in ROS and in bags: which nodes are published when
(`ros.terrain.TerrainFeed`), the PointCloud2 and MarkerArray against the Jazzy definitions and CDR,
the reset_terrain service of the runtime, and a deformable run's bag."""
import numpy as np
import pytest

from rft_sim_ros.ros import messages, topics
from rft_sim_ros.ros.bag import bag_topics, read_messages
from rft_sim_ros.ros.factory import RosbagsFactory, jazzy_typestore
from rft_sim_ros.ros.recording import BagRecorder
from rft_sim_ros.ros.runtime import SimRuntime
from rft_sim_ros.ros.terrain import TILE, TerrainFeed
from rft_sim_ros.sand.deformable import DeformableSand
from rft_sim_ros.sand.surface import HeightGrid, Plane, Slope
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.runner import run_scene
from rft_sim_ros.sim.simulation import Simulation

TS = jazzy_typestore()
FACTORY = RosbagsFactory(TS)
BED = {'sand.deformable.enabled': True, 'sand.deformable.size': [0.5, 0.5]}


def roundtrip(msg):
    return TS.deserialize_cdr(TS.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)


def cloud_points(cloud):
    """(N, 3) float32 x, y, z of a PointCloud2 with the layout terrain_cloud_message writes."""
    return np.frombuffer(bytes(cloud.data), dtype='<f4').reshape(-1, 3)


def node_xyz(surface, j, i):
    return (surface.origin[0] + i * surface.spacing[0], surface.origin[1] + j * surface.spacing[1],
            surface.grid[j, i])


def shown(markers):
    """{id: Marker} that RViz shows after the terrain markers `markers` in order: a DELETEALL
    of the namespace clears them, an ADD replaces its id's, a DELETE removes it."""
    tiles = {}
    for marker in markers:
        assert marker.ns == messages.TERRAIN_MARKER_NS
        if marker.action == messages.MARKER_DELETEALL:
            tiles.clear()
        elif marker.action == messages.MARKER_ADD:
            tiles[marker.id] = marker
        else:
            assert marker.action == messages.MARKER_DELETE and not marker.points
            tiles.pop(marker.id, None)
    return tiles


def shown_points(markers):
    """(K, 3) x, y, z of every point RViz shows after `markers`, sorted by x, y, z."""
    points = np.array([[p.x, p.y, p.z] for marker in shown(markers).values()
                       for p in marker.points]).reshape(-1, 3)
    return points[np.lexsort(points.T[::-1])]


def deformed_points(bed):
    """(K, 3) x, y, z of the nodes of `bed` that differ from its pristine surface, sorted
    as `shown_points`."""
    points = np.array([node_xyz(bed, j, i)
                       for j, i in zip(*np.nonzero(bed.grid != bed.pristine))]).reshape(-1, 3)
    return points[np.lexsort(points.T[::-1])]


def published_markers(update):
    """The MarkerArrays that the publication of `update` (a TerrainUpdate) sends on
    /rft/terrain/marker, through CDR."""
    arrays = [roundtrip(message) for topic, message in messages.terrain_messages(FACTORY, update)
              if topic == topics.TERRAIN_MARKER]
    assert all(array.__msgtype__ == topics.MARKER_ARRAY_TYPE for array in arrays)
    return arrays


def marker_array(update):
    """The one MarkerArray that the publication of `update` sends."""
    (array,) = published_markers(update)
    return array


def markers_of(updates):
    """The terrain markers that the publications of `updates` (TerrainUpdates) send, in
    order."""
    return [marker for update in updates for array in published_markers(update)
            for marker in array.markers]


@pytest.mark.parametrize('surface', [Plane(0.1), Slope(0.0, 10.0, 30.0)])
def test_analytic_surfaces_publish_nothing(surface):
    feed = TerrainFeed(surface)
    assert not feed.active and feed.update(0.0) is None
    assert topics.TERRAIN not in topics.published_topics([], plates=False, terrain=feed.active)


def test_a_static_grid_is_published_whole_once():
    grid = HeightGrid(np.arange(12.0).reshape(3, 4) * 0.01, size=(0.3, 0.2), center=(1.0, 2.0))
    feed = TerrainFeed(grid, rate=2.0)
    update = feed.update(0.0)
    assert update.points.dtype == np.float32 and update.points.shape == (12, 3)
    assert update.shape == (3, 4)  # the whole grid: its rows and columns
    np.testing.assert_allclose(update.points[5], node_xyz(grid, 1, 1), atol=1e-6)
    np.testing.assert_allclose(update.points[:, 2], grid.grid.ravel(), atol=1e-7)
    assert update.clear and update.tiles == () and update.spacing == pytest.approx(0.1)
    (deleteall,) = marker_array(update).markers  # nothing deformed: only the clearing
    assert deleteall.action == messages.MARKER_DELETEALL
    assert feed.update(10.0) is None  # nothing changed: nothing more


def test_deformable_sand_publishes_changed_nodes_at_the_rate_and_after_a_reset():
    bed = DeformableSand(Plane(0.1), size=(0.2, 0.2), cell=0.02)
    feed = TerrainFeed(bed, rate=2.0)
    assert len(feed.update(0.0).points) == bed.grid.size
    with bed.editing() as heights:
        heights[3, 4] -= 0.01  # a footprint
        heights[3, 5] += 0.01  # its rim
    assert feed.update(0.4) is None  # within 0.5 s of the last publication
    update = feed.update(0.5)
    np.testing.assert_allclose(update.points, [node_xyz(bed, 3, 4), node_xyz(bed, 3, 5)],
                               atol=1e-6)
    assert update.shape == (1, 2)  # changed nodes: one row
    (tile,) = update.tiles  # 11 x 11 nodes: one tile
    assert tile.index == 0 and not update.clear
    np.testing.assert_allclose(tile.change, [-0.01, 0.01])
    np.testing.assert_allclose(tile.deformed, update.points)
    with bed.editing() as heights:
        heights[3, 5] -= 0.01
    update = feed.update(1.2)
    np.testing.assert_allclose(update.points, [node_xyz(bed, 3, 5)], atol=1e-6)
    np.testing.assert_allclose(update.tiles[0].deformed, [node_xyz(bed, 3, 4)], atol=1e-6)
    bed.reset()
    update = feed.update(1.7)
    np.testing.assert_allclose(update.points, [node_xyz(bed, 3, 4)], atol=1e-6)
    assert update.points[0, 2] == pytest.approx(0.1)
    assert len(update.tiles) == 1 and len(update.tiles[0].deformed) == 0  # pristine again
    with bed.editing() as heights:
        heights[0, 0] += 0.001
    assert feed.update(1.8) is None  # not due yet
    np.testing.assert_allclose(feed.update(1.8, due=True).points, [node_xyz(bed, 0, 0)],
                               atol=1e-6)


def test_the_changes_a_walk_makes_are_all_published():
    """The hexapod walking on deformable sand: publications of the changed nodes only (found
    in the blocks the sand changed, `DeformableSand.blocks_changed_since`), applied in turn to
    the first whole cloud, give the bed as it is at each publication."""
    sim = Simulation(load_scene('hexapod', {'sand.deformable.enabled': True}))
    bed = sim.engine.surface
    feed = TerrainFeed(bed, rate=2.0)
    first = feed.update(sim.time)
    shown = first.points[:, 2].astype(float).reshape(bed.grid.shape)
    changes = 0
    for _ in range(5):  # the drop, then the first steps of the walk
        sim.step(375)  # 0.3 s
        update = feed.update(sim.time, due=True)
        if update is not None:
            i = np.rint((update.points[:, 0] - bed.origin[0]) / bed.spacing[0]).astype(int)
            j = np.rint((update.points[:, 1] - bed.origin[1]) / bed.spacing[1]).astype(int)
            shown[j, i] = update.points[:, 2]
            changes += len(update.points)
        np.testing.assert_allclose(shown, bed.grid, rtol=0, atol=1e-7)  # (float32 points)
    assert changes > 200  # the feet's footprints and rims


@pytest.mark.parametrize('deformable', [False, True])
def test_resend_publishes_the_whole_grid_at_once_for_a_late_subscriber(deformable):
    """What the node does when a subscriber joins: the next update carries every node (at the
    grid's current heights, at once, whatever the rate), then changes only again."""
    grid = HeightGrid(np.zeros((5, 6)), size=(0.5, 0.4))
    surface = DeformableSand(grid, size=(0.2, 0.2), cell=0.02) if deformable else grid
    feed = TerrainFeed(surface, rate=2.0)
    assert len(feed.update(0.0).points) == surface.grid.size
    assert feed.update(0.1) is None
    if deformable:  # (a rigid grid's heights are read-only)
        with surface.editing() as heights:
            heights[2, 3] -= 0.01
    feed.resend_cloud()
    update = feed.update(0.2)  # within 0.5 s of the last publication: due anyway
    assert len(update.points) == surface.grid.size and update.shape == surface.grid.shape
    np.testing.assert_allclose(update.points[:, 2], surface.grid.ravel(), atol=1e-7)
    assert not update.clear  # the markers: only the changed tile
    assert [len(tile.deformed) for tile in update.tiles] == ([1] if deformable else [])
    # no marker changed on a rigid grid: the cloud alone, no MarkerArray
    assert len(published_markers(update)) == (1 if deformable else 0)
    assert feed.update(0.8) is None  # nothing changed since


def test_only_the_tiles_holding_a_changed_node_are_rebuilt():
    """Markers per square tile of TILE nodes: a publication carries only the tiles where a
    node changed (all its deformed nodes), an empty one where the tile is pristine again;
    the markers shown, applied in order, are the deformation whatever it was before."""
    bed = DeformableSand(Plane(0.0), size=(0.99, 0.69), cell=0.01)  # 100 x 70 nodes
    assert bed.grid.shape == (70, 100) and TILE == 32  # tiles: 3 rows of 4
    feed = TerrainFeed(bed, rate=2.0)
    with bed.editing() as heights:
        heights[:40, :40] -= 0.001  # tiles 0, 1, 4 and 5
        heights[69, 99] += 0.002  # the last tile, 11
    first = feed.update(0.0)
    assert first.clear and [tile.index for tile in first.tiles] == [0, 1, 4, 5, 11]
    assert [(m.action, m.id) for m in marker_array(first).markers] == [  # one message
        (messages.MARKER_DELETEALL, 0)] + [(messages.MARKER_ADD, k) for k in (0, 1, 4, 5, 11)]
    assert len(first.tiles[0].deformed) == TILE * TILE and len(first.tiles[1].deformed) == 8 * 32
    np.testing.assert_allclose(first.tiles[-1].deformed, [node_xyz(bed, 69, 99)], atol=1e-6)
    np.testing.assert_allclose(first.tiles[-1].change, [0.002])
    with bed.editing() as heights:
        heights[35, 3] -= 0.001  # in tile 4 (row 1, column 0)
        heights[69, 99] = 0.0  # tile 11 back to pristine
    update = feed.update(0.5)
    assert not update.clear and [tile.index for tile in update.tiles] == [4, 11]
    assert [(m.action, m.id) for m in marker_array(update).markers] == [
        (messages.MARKER_ADD, 4), (messages.MARKER_DELETE, 11)]
    assert len(update.tiles[0].deformed) == 8 * 32 and len(update.tiles[1].deformed) == 0
    np.testing.assert_allclose(update.tiles[0].change[TILE * 3 + 3], -0.002)  # [35, 3]
    np.testing.assert_allclose(shown_points(markers_of([first, update])),
                               deformed_points(bed), atol=1e-6)


def test_a_marker_resend_publishes_every_tile_and_no_cloud_unless_it_changed():
    """What the node does when a subscriber of the markers joins: the next update (at once)
    clears the markers and carries every deformed tile; the cloud only holds what changed
    since the last publication (nothing: no cloud)."""
    bed = DeformableSand(Plane(0.0), size=(0.99, 0.69), cell=0.01)
    feed = TerrainFeed(bed, rate=2.0)
    feed.update(0.0)
    with bed.editing() as heights:
        heights[5, 5] -= 0.001
        heights[50, 90] -= 0.001
    feed.update(0.5)
    feed.resend_markers()
    update = feed.update(0.6)
    assert update.points is None and update.shape is None  # nothing changed: no cloud
    assert update.clear and [tile.index for tile in update.tiles] == [0, 6]
    with bed.editing() as heights:
        heights[5, 5] = 0.0
    feed.resend_markers()
    update = feed.update(0.7)
    np.testing.assert_allclose(update.points, [node_xyz(bed, 5, 5)], atol=1e-6)
    assert update.clear and [tile.index for tile in update.tiles] == [6]
    markers = marker_array(update).markers
    assert [(m.action, m.id) for m in markers] == [(3, 0), (0, 6)]  # DELETEALL, ADD
    assert feed.update(0.8) is None


@pytest.mark.parametrize('cycle', [0.03, 0.01, 0.07])
def test_the_mean_rate_is_the_rate_asked_for(cycle):
    """Publications on a fixed grid of sim time: with a surface that changes every publish
    cycle (every `cycle` s), 2 Hz over 100 s of sim time is 200 publications, none closer
    than a cycle, and no gap longer than a period and a cycle."""
    bed = DeformableSand(Plane(0.0), size=(0.2, 0.2), cell=0.02)
    feed = TerrainFeed(bed, rate=2.0)
    times = []
    for k in range(1, round(100.0 / cycle) + 1):
        with bed.editing() as heights:
            heights[0, 0] += 1e-4
        if feed.update(k * cycle) is not None:
            times.append(k * cycle)
    assert abs(len(times) - 200) <= 1
    assert np.diff(times).max() < 0.5 + cycle + 1e-9


def test_a_publication_between_the_grids_times_keeps_the_grid():
    """A re-send for a new subscriber (or a reset's publication) between two of the grid's
    times publishes at once without moving the grid: the changes still go out at 0.5 s."""
    bed = DeformableSand(Plane(0.0), size=(0.2, 0.2), cell=0.02)
    feed = TerrainFeed(bed, rate=2.0)
    assert feed.update(0.0) is not None
    feed.resend_markers()
    assert feed.update(0.3).clear
    with bed.editing() as heights:
        heights[0, 0] -= 0.001
    assert feed.update(0.49) is None
    assert feed.update(0.5) is not None


def test_a_schedule_that_fell_behind_restarts_from_now():
    """After the surface stood still, the first change is published at once and the next
    a period later, not in a burst catching up the missed times."""
    bed = DeformableSand(Plane(0.0), size=(0.2, 0.2), cell=0.02)
    feed = TerrainFeed(bed, rate=2.0)
    feed.update(0.0)
    with bed.editing() as heights:
        heights[0, 0] += 0.01
    assert feed.update(10.0) is not None
    with bed.editing() as heights:
        heights[0, 0] += 0.01
    assert feed.update(10.1) is None and feed.update(10.49) is None
    assert feed.update(10.5) is not None


def test_rate_is_checked():
    with pytest.raises(ValueError, match='terrain_rate must be a finite number > 0'):
        TerrainFeed(Plane(), rate=0.0)


def test_terrain_messages_fill_the_jazzy_types_and_round_trip_cdr():
    bed = DeformableSand(Plane(0.1), size=(0.2, 0.3), cell=0.02)
    feed = TerrainFeed(bed)
    whole = roundtrip(messages.terrain_cloud_message(FACTORY, feed.update(0.0)))
    ny, nx = bed.grid.shape
    assert (ny, nx) == (16, 11)
    assert (whole.height, whole.width, whole.row_step) == (ny, nx, 12 * nx)  # organized
    grid = cloud_points(whole).reshape(ny, nx, 3)  # row-major, [iy, ix]
    np.testing.assert_allclose(grid[4, 7], node_xyz(bed, 4, 7), atol=1e-6)
    np.testing.assert_allclose(grid[:, :, 2], bed.grid, atol=1e-7)
    with bed.editing() as heights:
        heights[2, 2] -= 0.03
        heights[2, 3] += 0.005
    update = feed.update(1.25)
    (cloud_topic, cloud), (marker_topic, array) = messages.terrain_messages(FACTORY, update)
    assert (cloud_topic, marker_topic) == (topics.TERRAIN, topics.TERRAIN_MARKER)
    assert array.__msgtype__ == topics.MARKER_ARRAY_TYPE
    cloud, (marker,) = roundtrip(cloud), roundtrip(array).markers
    assert (marker.ns, marker.id) == (messages.TERRAIN_MARKER_NS, 0)  # the one tile
    assert cloud.header.frame_id == topics.ODOM_FRAME == marker.header.frame_id
    assert (cloud.header.stamp.sec, cloud.header.stamp.nanosec) == (1, 250_000_000)
    assert (cloud.height, cloud.width, cloud.point_step, cloud.row_step) == (1, 2, 12, 24)
    assert [(f.name, f.offset, f.datatype, f.count) for f in cloud.fields] == [
        ('x', 0, 7, 1), ('y', 4, 7, 1), ('z', 8, 7, 1)]
    assert not cloud.is_bigendian and cloud.is_dense
    np.testing.assert_array_equal(cloud_points(cloud), update.points)
    assert (marker.type, marker.action) == (8, 0)  # POINTS, ADD
    np.testing.assert_allclose([[p.x, p.y, p.z] for p in marker.points],
                               update.tiles[0].deformed)
    assert marker.scale.x == pytest.approx(0.02)
    dug, piled = marker.colors
    assert (dug.b, dug.r) == (1.0, 0.0)  # 3 cm down: past full scale, full blue
    assert piled.r > piled.b and piled.r < 1.0  # 5 mm up: partly red
    bed.reset()
    (marker,) = marker_array(feed.update(2.0)).markers
    assert (marker.action, marker.id) == (2, 0) and not marker.points  # pristine: DELETE
    feed.resend_markers()
    # pristine, sent whole: the namespace's markers deleted
    (marker,) = marker_array(feed.update(2.1)).markers
    assert (marker.action, marker.ns, marker.type) == (3, messages.TERRAIN_MARKER_NS, 8)
    assert not marker.points and marker.header.frame_id == topics.ODOM_FRAME


def _lift(sim):
    """Take the plate out of the sand (0.3 m up, at rest): its footprint is committed at the
    next step."""
    sim.data.qpos[2] = 0.3
    sim.data.qvel[:] = 0.0


class _Sink:
    def __init__(self):
        self.terrain = []

    def write_state(self, state):
        pass

    def write_diagnostics(self, state, status):
        pass

    def write_terrain(self, update):
        self.terrain.append(update)


def test_runtime_publishes_terrain_with_the_state_and_resets_it():
    sim = Simulation(load_scene('plate_drop', BED))
    sink = _Sink()
    feed = TerrainFeed(sim.engine.surface, rate=4.0)
    runtime = SimRuntime(sim, sink, publish_rate=100.0, paused=True, terrain=feed)
    for _ in range(20):  # 0.2 s: the plate is at rest in the sand
        assert runtime.step().success
    _lift(sim)
    for _ in range(10):
        runtime.step()
    bed = sim.engine.surface
    assert len(sink.terrain[0].points) == bed.grid.size and sink.terrain[0].time == pytest.approx(0.01)
    assert (bed.grid < bed.pristine).any()  # the footprint
    times = [u.time for u in sink.terrain]
    assert np.all(np.diff(times) >= 0.25 - 1e-9)  # terrain_rate 4 Hz at most
    assert sink.terrain[-1].time > 0.2  # published after the lift
    np.testing.assert_allclose(shown_points(markers_of(sink.terrain)), deformed_points(bed),
                               atol=1e-6)
    result = runtime.reset_terrain()
    assert result.success and 'reset' in result.message
    np.testing.assert_array_equal(bed.grid, bed.pristine)
    time = sim.time
    for _ in range(30):
        runtime.step()
    assert sim.time > time  # sim time goes on
    assert not shown(markers_of(sink.terrain))  # the pristine surface was published


@pytest.mark.parametrize('service', ['reset_terrain', 'reset'])
def test_a_terrain_reset_is_published_at_once_while_paused(service):
    """reset_terrain and reset publish the pristine surface at once, not when the simulation
    resumes and the rate is due (RViz would show the old footprints meanwhile)."""
    sim = Simulation(load_scene('plate_drop', BED))
    sink = _Sink()
    runtime = SimRuntime(sim, sink, publish_rate=100.0, paused=True,
                         terrain=TerrainFeed(sim.engine.surface, rate=0.5))
    bed = sim.engine.surface
    with bed.editing() as heights:
        heights[10, 10] -= 0.01  # a footprint away from the plate
    assert runtime.step().success
    assert len(sink.terrain) == 1 and len(shown_points(markers_of(sink.terrain))) == 1
    assert getattr(runtime, service)().success
    assert len(sink.terrain) == 2  # at once: paused, 0.01 s after a publication at 0.5 Hz
    update = sink.terrain[-1]
    assert update.time == sim.time and update.shape == (1, 1)
    assert not shown(markers_of(sink.terrain))
    np.testing.assert_allclose(update.points, [node_xyz(bed, 10, 10)], atol=1e-6)
    assert getattr(runtime, service)().success
    assert len(sink.terrain) == 2  # nothing changed: nothing published


@pytest.mark.parametrize('cloud', [True, False])
def test_a_new_subscriber_gets_the_surface_at_once_while_paused(cloud):
    """resend_terrain (a subscriber of the cloud, or of the markers, joined) publishes at
    once, paused: the whole grid for the cloud's, every deformed tile for the markers'; the
    other part only with what changed (nothing here)."""
    sim = Simulation(load_scene('plate_drop', BED))
    sink = _Sink()
    runtime = SimRuntime(sim, sink, publish_rate=100.0, paused=True,
                         terrain=TerrainFeed(sim.engine.surface, rate=0.5))
    runtime.resend_terrain(cloud=cloud, markers=not cloud)
    assert sink.terrain == []  # before the initial publication: that one carries everything
    bed = sim.engine.surface
    with bed.editing() as heights:
        heights[10, 10] -= 0.01  # a footprint away from the plate
    runtime.tick()  # the initial publication (paused)
    assert len(sink.terrain) == 1
    runtime.resend_terrain(cloud=cloud, markers=not cloud)
    assert len(sink.terrain) == 2  # at once: paused, right after a publication at 0.5 Hz
    update = sink.terrain[-1]
    assert update.time == sim.time
    if cloud:
        assert update.shape == bed.grid.shape and not update.clear and update.tiles == ()
    else:
        assert update.points is None and update.clear
        assert [len(tile.deformed) for tile in update.tiles] == [1]


def test_runtime_warns_once_when_plates_are_in_the_sand_outside_the_bed():
    small = {'sand.deformable.enabled': True, 'sand.deformable.size': [0.06, 0.06]}
    warnings = []
    sim = Simulation(load_scene('plate_drop', small))
    runtime = SimRuntime(sim, _Sink(), publish_rate=100.0, paused=True,
                         terrain=TerrainFeed(sim.engine.surface), warn=warnings.append)
    for _ in range(30):
        runtime.step()
    assert len(warnings) == 1 and 'outside the deformable bed' in warnings[0]
    runtime.reset()  # a new run: warned again if it happens again
    for _ in range(30):
        runtime.step()
    assert len(warnings) == 2


def test_reset_terrain_on_rigid_sand_is_refused_as_there_is_nothing_to_reset():
    """std_srvs/Trigger's success says the action ran: on rigid sand it cannot."""
    runtime = SimRuntime(Simulation(load_scene('plate_drop')), _Sink(), publish_rate=100.0)
    result = runtime.reset_terrain()
    assert not result.success and 'not deformable' in result.message


def test_a_deformable_runs_bag_holds_the_surface_where_it_changed(tmp_path):
    scene = load_scene('plate_drop', BED)
    run_scene(scene, out_dir=tmp_path, duration=0.3, progress=False, plots=False,
              recorders=[BagRecorder(tmp_path / 'bag', scene)], schedule=[(0.2, _lift)])
    final = np.load(tmp_path / 'terrain.npy')
    recorded = bag_topics(tmp_path / 'bag')
    assert recorded[topics.TERRAIN].msgtype == topics.POINT_CLOUD_TYPE
    assert recorded[topics.TERRAIN_MARKER].msgtype == topics.MARKER_ARRAY_TYPE
    # the whole bed at the start, then the footprint: at the rate or, the last, at the end
    assert recorded[topics.TERRAIN].count >= 2
    arrays = [(time_ns, array) for _, time_ns, array
              in read_messages(tmp_path / 'bag', [topics.TERRAIN_MARKER])]
    times = [time_ns for time_ns, _ in arrays]
    assert times[0] == 0 and times == sorted(set(times))  # one MarkerArray a publication
    assert arrays[0][1].markers[0].action == messages.MARKER_DELETEALL
    heights = None
    bed = Simulation(scene).engine.surface  # the pristine bed: its node coordinates
    for _, _, cloud in read_messages(tmp_path / 'bag', [topics.TERRAIN]):
        points = cloud_points(cloud)
        i = np.rint((points[:, 0] - bed.origin[0]) / bed.spacing[0]).astype(int)
        j = np.rint((points[:, 1] - bed.origin[1]) / bed.spacing[1]).astype(int)
        if heights is None:  # the whole grid, organized as the grid
            assert len(points) == final.size and (cloud.height, cloud.width) == final.shape
            heights = np.full(final.shape, np.nan)
        else:  # the changes
            assert cloud.height == 1 and cloud.width == len(points)
        heights[j, i] = points[:, 2]
    assert not np.array_equal(final, bed.pristine)  # the plate left its mark
    np.testing.assert_allclose(heights, final.astype(np.float32), rtol=0, atol=1e-7)
    with bed.editing() as heights:
        heights[:] = final
    np.testing.assert_allclose(
        shown_points([marker for _, array in arrays for marker in array.markers]),
        deformed_points(bed), atol=1e-6)


def test_a_rigid_runs_bag_has_no_terrain_topic(tmp_path):
    scene = load_scene('plate_drop')
    run_scene(scene, duration=0.02, progress=False, recorders=[BagRecorder(tmp_path / 'b', scene)])
    assert topics.TERRAIN not in bag_topics(tmp_path / 'b')
