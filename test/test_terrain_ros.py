"""The sand surface seen in ROS and in bags: which nodes are published when
(`ros.terrain.TerrainFeed`), the PointCloud2 and Marker against the Jazzy definitions and CDR,
the reset_terrain service of the runtime, and a deformable run's bag."""
import numpy as np
import pytest

from rft_sim_ros.ros import messages, topics
from rft_sim_ros.ros.bag import bag_topics, read_messages
from rft_sim_ros.ros.factory import RosbagsFactory, jazzy_typestore
from rft_sim_ros.ros.recording import BagRecorder
from rft_sim_ros.ros.runtime import SimRuntime
from rft_sim_ros.ros.terrain import TerrainFeed
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
    assert len(update.deformed) == 0 and update.spacing == pytest.approx(0.1)
    assert feed.update(10.0) is None  # nothing changed: nothing more


def test_deformable_sand_publishes_changed_nodes_at_the_rate_and_after_a_reset():
    bed = DeformableSand(Plane(0.1), size=(0.2, 0.2), cell=0.02)
    feed = TerrainFeed(bed, rate=2.0)
    assert len(feed.update(0.0).points) == bed.grid.size
    bed.grid[3, 4] -= 0.01  # a footprint
    bed.grid[3, 5] += 0.01  # its rim
    assert feed.update(0.4) is None  # within 0.5 s of the last publication
    update = feed.update(0.5)
    np.testing.assert_allclose(update.points, [node_xyz(bed, 3, 4), node_xyz(bed, 3, 5)],
                               atol=1e-6)
    assert update.shape == (1, 2)  # changed nodes: one row
    np.testing.assert_allclose(update.change, [-0.01, 0.01])
    np.testing.assert_allclose(update.deformed, update.points)
    bed.grid[3, 5] -= 0.01
    update = feed.update(1.2)
    np.testing.assert_allclose(update.points, [node_xyz(bed, 3, 5)], atol=1e-6)
    np.testing.assert_allclose(update.deformed, [node_xyz(bed, 3, 4)], atol=1e-6)
    bed.reset()
    update = feed.update(1.7)
    np.testing.assert_allclose(update.points, [node_xyz(bed, 3, 4)], atol=1e-6)
    assert update.points[0, 2] == pytest.approx(0.1) and len(update.deformed) == 0
    bed.grid[0, 0] += 0.001
    assert feed.update(1.8) is None  # not due yet
    np.testing.assert_allclose(feed.update(1.8, due=True).points, [node_xyz(bed, 0, 0)],
                               atol=1e-6)


@pytest.mark.parametrize('deformable', [False, True])
def test_resend_publishes_the_whole_grid_at_once_for_a_late_subscriber(deformable):
    """What the node does when a subscriber joins: the next update carries every node (at the
    grid's current heights, at once, whatever the rate), then changes only again."""
    grid = HeightGrid(np.zeros((5, 6)), size=(0.5, 0.4))
    surface = DeformableSand(grid, size=(0.2, 0.2), cell=0.02) if deformable else grid
    feed = TerrainFeed(surface, rate=2.0)
    assert len(feed.update(0.0).points) == surface.grid.size
    assert feed.update(0.1) is None
    surface.grid[2, 3] -= 0.01
    feed.resend()
    update = feed.update(0.2)  # within 0.5 s of the last publication: due anyway
    assert len(update.points) == surface.grid.size and update.shape == surface.grid.shape
    np.testing.assert_allclose(update.points[:, 2], surface.grid.ravel(), atol=1e-7)
    assert len(update.deformed) == (1 if deformable else 0)
    assert feed.update(0.8) is None  # nothing changed since


@pytest.mark.parametrize('cycle', [0.03, 0.01, 0.07])
def test_the_mean_rate_is_the_rate_asked_for(cycle):
    """Publications on a fixed grid of sim time: with a surface that changes every publish
    cycle (every `cycle` s), 2 Hz over 100 s of sim time is 200 publications, none closer
    than a cycle, and no gap longer than a period and a cycle."""
    bed = DeformableSand(Plane(0.0), size=(0.2, 0.2), cell=0.02)
    feed = TerrainFeed(bed, rate=2.0)
    times = []
    for k in range(1, round(100.0 / cycle) + 1):
        bed.grid[0, 0] += 1e-4
        if feed.update(k * cycle) is not None:
            times.append(k * cycle)
    assert abs(len(times) - 200) <= 1
    assert np.diff(times).max() < 0.5 + cycle + 1e-9


def test_a_schedule_that_fell_behind_restarts_from_now():
    """After the surface stood still, the first change is published at once and the next
    a period later, not in a burst catching up the missed times."""
    bed = DeformableSand(Plane(0.0), size=(0.2, 0.2), cell=0.02)
    feed = TerrainFeed(bed, rate=2.0)
    feed.update(0.0)
    bed.grid[0, 0] += 0.01
    assert feed.update(10.0) is not None
    bed.grid[0, 0] += 0.01
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
    bed.grid[2, 2] -= 0.03
    bed.grid[2, 3] += 0.005
    update = feed.update(1.25)
    (cloud_topic, cloud), (marker_topic, marker) = messages.terrain_messages(FACTORY, update)
    assert (cloud_topic, marker_topic) == (topics.TERRAIN, topics.TERRAIN_MARKER)
    cloud, marker = roundtrip(cloud), roundtrip(marker)
    assert cloud.header.frame_id == topics.ODOM_FRAME == marker.header.frame_id
    assert (cloud.header.stamp.sec, cloud.header.stamp.nanosec) == (1, 250_000_000)
    assert (cloud.height, cloud.width, cloud.point_step, cloud.row_step) == (1, 2, 12, 24)
    assert [(f.name, f.offset, f.datatype, f.count) for f in cloud.fields] == [
        ('x', 0, 7, 1), ('y', 4, 7, 1), ('z', 8, 7, 1)]
    assert not cloud.is_bigendian and cloud.is_dense
    np.testing.assert_array_equal(cloud_points(cloud), update.points)
    assert (marker.type, marker.action) == (8, 0)  # POINTS, ADD
    np.testing.assert_allclose([[p.x, p.y, p.z] for p in marker.points], update.deformed)
    assert marker.scale.x == pytest.approx(0.02)
    dug, piled = marker.colors
    assert (dug.b, dug.r) == (1.0, 0.0)  # 3 cm down: past full scale, full blue
    assert piled.r > piled.b and piled.r < 1.0  # 5 mm up: partly red
    bed.reset()
    marker = roundtrip(messages.terrain_marker_message(FACTORY, feed.update(2.0)))
    assert marker.action == 2 and not marker.points  # pristine again: DELETE


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
    last = sink.terrain[-1]
    assert last.time > 0.2  # published after the lift
    np.testing.assert_allclose(last.deformed[:, 2], bed.grid[bed.grid != bed.pristine],
                               atol=1e-7)
    result = runtime.reset_terrain()
    assert result.success and 'reset' in result.message
    np.testing.assert_array_equal(bed.grid, bed.pristine)
    time = sim.time
    for _ in range(30):
        runtime.step()
    assert sim.time > time  # sim time goes on
    assert len(sink.terrain[-1].deformed) == 0  # the pristine surface was published


@pytest.mark.parametrize('service', ['reset_terrain', 'reset'])
def test_a_terrain_reset_is_published_at_once_while_paused(service):
    """reset_terrain and reset publish the pristine surface at once, not when the simulation
    resumes and the rate is due (RViz would show the old footprints meanwhile)."""
    sim = Simulation(load_scene('plate_drop', BED))
    sink = _Sink()
    runtime = SimRuntime(sim, sink, publish_rate=100.0, paused=True,
                         terrain=TerrainFeed(sim.engine.surface, rate=0.5))
    bed = sim.engine.surface
    bed.grid[10, 10] -= 0.01  # a footprint away from the plate
    assert runtime.step().success
    assert len(sink.terrain) == 1 and len(sink.terrain[0].deformed) == 1
    assert getattr(runtime, service)().success
    assert len(sink.terrain) == 2  # at once: paused, 0.01 s after a publication at 0.5 Hz
    update = sink.terrain[-1]
    assert update.time == sim.time and update.shape == (1, 1) and len(update.deformed) == 0
    np.testing.assert_allclose(update.points, [node_xyz(bed, 10, 10)], atol=1e-6)
    assert getattr(runtime, service)().success
    assert len(sink.terrain) == 2  # nothing changed: nothing published


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


def test_reset_terrain_on_rigid_sand_says_there_is_nothing_to_reset():
    runtime = SimRuntime(Simulation(load_scene('plate_drop')), _Sink(), publish_rate=100.0)
    result = runtime.reset_terrain()
    assert result.success and 'not deformable' in result.message


def test_a_deformable_runs_bag_holds_the_surface_where_it_changed(tmp_path):
    scene = load_scene('plate_drop', BED)
    run_scene(scene, out_dir=tmp_path, duration=0.3, progress=False, plots=False,
              recorders=[BagRecorder(tmp_path / 'bag', scene)], schedule=[(0.2, _lift)])
    final = np.load(tmp_path / 'terrain.npy')
    recorded = bag_topics(tmp_path / 'bag')
    assert recorded[topics.TERRAIN].msgtype == topics.POINT_CLOUD_TYPE
    # the whole bed at the start, then the footprint: at the rate or, the last, at the end
    assert recorded[topics.TERRAIN_MARKER].count == recorded[topics.TERRAIN].count >= 2
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


def test_a_rigid_runs_bag_has_no_terrain_topic(tmp_path):
    scene = load_scene('plate_drop')
    run_scene(scene, duration=0.02, progress=False, recorders=[BagRecorder(tmp_path / 'b', scene)])
    assert topics.TERRAIN not in bag_topics(tmp_path / 'b')
