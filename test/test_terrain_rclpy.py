"""The sand surface over rclpy: /rft/terrain (PointCloud2) and /rft/terrain/marker (one
MarkerArray a publication) of a deformable scene, the ~/reset_terrain service, and nothing
published for a plane.

Runs where ROS 2 Jazzy is sourced; skipped with the reason everywhere else. Where ROS is
sourced, pytest must be below 9 (requirements.txt): Jazzy's launch_testing pytest plugin,
which pytest then loads, does not load with pytest 9."""
import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy', reason='ROS 2 Jazzy (rclpy) is not installed here')
for _package in ('std_srvs.srv', 'sensor_msgs.msg', 'visualization_msgs.msg'):
    pytest.importorskip(_package, reason=f'ROS 2 package {_package} is not installed here')

from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import PointCloud2  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402
from visualization_msgs.msg import Marker, MarkerArray  # noqa: E402

from rft_sim_ros.ros import topics  # noqa: E402
from rft_sim_ros.ros.node import SimNode  # noqa: E402
from ros_test_support import SERVO_RIG  # noqa: E402

pytestmark = pytest.mark.ros

#: A 0.5 m x 0.5 m deformable bed of 1 cm cells (51 x 51 nodes) under the dropped plate.
BED = ['sand.deformable.enabled=true', 'sand.deformable.size=[0.5, 0.5]']


def _bed_node(ros, *parameters):
    """A node dropping a plate into a small deformable bed (with `parameters` besides), its
    terrain topics watched: (node, clouds, marker arrays, a reset_terrain client)."""
    clouds, arrays = [], []
    ros.probe.create_subscription(PointCloud2, topics.TERRAIN, clouds.append, 100)
    ros.probe.create_subscription(MarkerArray, topics.TERRAIN_MARKER, arrays.append, 100)
    reset_terrain = ros.probe.create_client(Trigger, '/rft_sim/reset_terrain')
    sim = ros.add(SimNode(context=ros.context, parameter_overrides=[
        Parameter('scene', value='plate_drop'), Parameter('scene_overrides', value=BED),
        Parameter('real_time_factor', value=1.0), *parameters]))
    return sim, clouds, arrays, reset_terrain


def points(cloud):
    return np.frombuffer(bytes(cloud.data), dtype='<f4').reshape(-1, 3)


def last_marker(arrays):
    """The last marker received: the last of the last MarkerArray of `arrays`."""
    return arrays[-1].markers[-1]


def test_deformable_sand_is_published_where_it_changed_and_reset_by_the_service(ros):
    sim, clouds, arrays, reset_terrain = _bed_node(ros, Parameter('terrain_rate', value=5.0))
    assert ros.spin_until(lambda: clouds and arrays)
    first = clouds[0]
    assert first.header.frame_id == topics.ODOM_FRAME and (first.height, first.width) == (51, 51)
    assert np.all(points(first)[:, 2] == 0.0)           # the pristine bed at surface height 0
    assert [m.action for m in arrays[0].markers] == [Marker.DELETEALL]  # nothing deformed yet
    assert ros.spin_until(lambda: sim.runtime.sim.time > 0.4, timeout=20.0)
    assert ros.call(ros.probe.pause, SetBool.Request(data=True)).success
    sim.runtime.sim.data.qpos[2] = 0.3                   # take the plate out of its footprint
    sim.runtime.sim.data.qvel[:] = 0.0
    assert ros.call(ros.probe.pause, SetBool.Request(data=False)).success
    assert ros.spin_until(lambda: last_marker(arrays).action == Marker.ADD, timeout=20.0)
    footprint = points(clouds[-1])
    assert clouds[-1].height == 1                        # changes: an unorganized cloud
    assert 0 < len(footprint) < 51 * 51 and footprint[:, 2].min() < -1e-3  # a crater
    assert len(last_marker(arrays).points) == len(last_marker(arrays).colors) > 0
    count = len(clouds)
    answer = ros.call(reset_terrain, Trigger.Request())
    assert answer.success and 'reset' in answer.message
    assert ros.spin_until(lambda: last_marker(arrays).action == Marker.DELETE, timeout=20.0)
    restored = np.concatenate([points(c) for c in clouds[count:]])
    assert np.all(restored[:, 2] == 0.0)                 # the changed nodes back at 0
    assert ros.catch_up(sim) and ros.probe.clock_times()[-1] > 0.4  # sim time went on


def test_a_late_subscriber_gets_the_whole_grid(ros):
    """A subscriber that joins after the first publication (RViz opened later, `ros2 topic
    echo`) gets every node at once, and the deformation markers."""
    sim = ros.add(SimNode(context=ros.context, parameter_overrides=[
        Parameter('scene', value='plate_drop'), Parameter('scene_overrides', value=BED),
        Parameter('real_time_factor', value=1.0), Parameter('terrain_rate', value=1.0)]))
    assert ros.spin_until(lambda: sim.runtime.sim.time > 0.3, timeout=20.0)
    clouds, arrays = [], []
    ros.probe.create_subscription(PointCloud2, topics.TERRAIN, clouds.append, 10)
    ros.probe.create_subscription(MarkerArray, topics.TERRAIN_MARKER, arrays.append, 10)
    assert ros.spin_until(lambda: clouds and arrays, timeout=20.0)
    assert (clouds[0].height, clouds[0].width) == (51, 51)
    # (the plate still in its footprint: pristine)
    assert [m.action for m in arrays[0].markers] == [Marker.DELETEALL]


def test_late_subscribers_get_the_surface_at_once_while_paused(ros):
    """Paused (no publish cycle comes): a new subscriber of the cloud gets the whole grid at
    once, and one of the markers every deformed tile (2 m bed of 1 cm cells: 7 x 7 tiles, all
    deformed here) after a DELETEALL, without the cloud being sent again; sim time stands
    still. The 50 markers come in one MarkerArray, so that a subscriber keeping only the last
    message (depth 1) gets them all."""
    sim = ros.add(SimNode(context=ros.context, parameter_overrides=[
        Parameter('scene', value='plate_drop'), Parameter('paused', value=True),
        Parameter('scene_overrides', value=['sand.deformable.enabled=true',
                                            'sand.deformable.size=[2.0, 2.0]'])]))
    assert ros.spin_until(lambda: ros.probe.clocks)     # the initial publication
    bed = sim.runtime.sim.engine.surface
    assert bed.grid.shape == (201, 201)
    with bed.editing() as heights:
        heights -= 0.001                                 # every node dug (no step: unpublished)
    ticks = len(ros.probe.clocks)
    clouds, arrays = [], []
    ros.probe.create_subscription(PointCloud2, topics.TERRAIN, clouds.append, 10)
    assert ros.spin_until(lambda: clouds)
    assert (clouds[0].height, clouds[0].width) == (201, 201)
    np.testing.assert_allclose(points(clouds[0])[:, 2], -0.001, atol=1e-7)
    ros.probe.create_subscription(MarkerArray, topics.TERRAIN_MARKER, arrays.append, 1)
    assert ros.spin_until(lambda: arrays)
    markers = arrays[0].markers
    assert len(markers) == 50
    assert markers[0].action == Marker.DELETEALL and markers[0].ns == 'rft_terrain'
    assert [m.id for m in markers[1:]] == list(range(49))  # by tile
    assert all(m.action == Marker.ADD for m in markers[1:])
    assert sum(len(m.points) for m in markers[1:]) == 201 * 201
    ros.spin_for(0.5)
    assert len(clouds) == 1 and len(arrays) == 1          # nothing more: nothing changed
    assert len(ros.probe.clocks) == ticks                 # paused all along


def test_only_a_new_subscriber_of_the_cloud_gets_the_whole_grid_again(ros, tmp_path):
    """A rigid height grid never changes: its cloud is published whole at the start, as an
    organized cloud (rows x columns, row-major), and again only when a subscriber of the
    cloud joins, not one of the markers (that one gets the markers alone)."""
    heights = np.add.outer(np.linspace(0.0, 0.02, 4), np.linspace(0.0, 0.01, 6))  # [iy, ix]
    np.save(tmp_path / 'grid.npy', heights)
    clouds, late = [], []
    ros.probe.create_subscription(PointCloud2, topics.TERRAIN, clouds.append, 10)
    sim = ros.add(SimNode(context=ros.context, parameter_overrides=[
        Parameter('scene', value='plate_drop'), Parameter('real_time_factor', value=1.0),
        Parameter('terrain_rate', value=10.0), Parameter('scene_overrides', value=[
            'sand.surface.type=grid', f'sand.surface.file={tmp_path / "grid.npy"}',
            'sand.surface.size=[0.5, 0.3]'])]))
    assert ros.spin_until(lambda: clouds)
    whole = clouds[0]
    assert (whole.height, whole.width, whole.row_step) == (4, 6, 6 * 12)
    grid = points(whole).reshape(4, 6, 3)
    np.testing.assert_allclose(grid[:, :, 2], heights, atol=1e-7)
    np.testing.assert_allclose(grid[2, 5, :2], [0.25, 0.05], atol=1e-6)  # x along a row
    ros.spin_for(1.0)
    count = len(clouds)
    ros.probe.create_subscription(MarkerArray, topics.TERRAIN_MARKER, lambda m: None, 10)
    assert ros.spin_until(lambda: sim.count_subscribers(topics.TERRAIN_MARKER) == 1)
    ros.spin_for(1.0)  # ten publication times at 10 Hz
    assert len(clouds) == count
    ros.probe.create_subscription(PointCloud2, topics.TERRAIN, late.append, 10)
    assert ros.spin_until(lambda: late)
    assert (late[0].height, late[0].width) == (4, 6)


def test_a_terrain_reset_while_paused_is_published_at_once(ros):
    """reset_terrain and reset while paused: the pristine surface is published at once, no
    step needed, sim time standing still."""
    sim, clouds, arrays, reset_terrain = _bed_node(  # each step publishes the changes
        ros, Parameter('terrain_rate', value=1000.0), Parameter('paused', value=True))
    assert ros.spin_until(lambda: clouds and arrays)
    bed = sim.runtime.sim.engine.surface
    for service in (reset_terrain, ros.probe.reset):
        with bed.editing() as heights:
            heights[10, 10] -= 0.01  # a footprint, away from the plate
        assert ros.call(ros.probe.step, Trigger.Request()).success
        assert ros.spin_until(lambda: last_marker(arrays).action == Marker.ADD)
        ticks, count = len(ros.probe.clocks), len(clouds)
        assert ros.call(service, Trigger.Request()).success
        assert ros.spin_until(lambda: last_marker(arrays).action == Marker.DELETE)
        assert ros.spin_until(lambda: len(clouds) == count + 1)
        restored = points(clouds[-1])
        assert len(restored) >= 1 and np.all(restored[:, 2] == 0.0)  # back at the surface
        assert len(ros.probe.clocks) == ticks            # no step: sim time stood still


def test_a_plane_publishes_no_terrain_and_reset_terrain_is_refused(ros):
    reset_terrain = ros.probe.create_client(Trigger, '/rft_sim/reset_terrain')
    sim = ros.add(SimNode(context=ros.context, parameter_overrides=[
        Parameter('scene', value=SERVO_RIG)]))
    assert ros.spin_until(lambda: ros.probe.clocks)
    assert sim.count_publishers(topics.TERRAIN) == 0
    answer = ros.call(reset_terrain, Trigger.Request())
    assert not answer.success and 'not deformable' in answer.message
