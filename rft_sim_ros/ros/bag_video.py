"""A run's video made again from its rosbag2, without simulating: `render_bag` (the
renderer's pieces, `render`, driven by the bag's messages).

The bag is one `rft-sim run` wrote (DIR/bag) or one `ros2 bag record` made of the node's
topics. The scene it ran (its summary.json's `scene_config`, or one given) builds the
Simulation only for its model and sand, which is not stepped past its start; each publish
cycle of the bag (messages of one header stamp, sim time) then poses the drawn copy
(`render.stage.Stage`): the joints from /joint_states, the base from /odom (the root's free
joint set so that the base body lies where /odom says), deformable sand from /rft/terrain (the
whole bed first, then its changed nodes), the legs' forces from /rft/<leg>/wrench at their
points on /tf, the plates from /rft/plates where the bag has them (drawn in the bag's
colours), zeta from /diagnostics. Frames are rendered at the video's rate as in
`render.recorder`. Joints the bag does not name (unnamed, ball joints) stay where the scene
starts them.
"""
import numpy as np
import mujoco

from ..render.decorations import Plates
from ..render.encoder import Mp4Writer
from ..render.frames import FramePainter
from ..render.recorder import overlay
from ..render.stage import Stage
from ..robot.sand_bodies import free_root_joint
from . import topics
from .bag import read_messages


class BagPoser:
    """Poses `stage` (render.stage.Stage) from the node's messages; `base`: the base body's name."""

    def __init__(self, stage, base):
        model = stage.model
        self.stage, self.model = stage, model
        self.qpos = stage.data.qpos.copy()
        self._base = model.body(base).id
        self._root_joint = free_root_joint(model, self._base)
        self._joints = {}
        movable = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        for j in range(model.njnt):
            if int(model.jnt_type[j]) in movable:
                self._joints[model.joint(j).name] = int(model.jnt_qposadr[j])
        self.missing = set()  # joint names of /joint_states the model does not have

    def joints(self, names, positions):
        """Joint positions (rad or m) by name."""
        for name, value in zip(names, positions):
            address = self._joints.get(name)
            if address is None:
                self.missing.add(name)
            else:
                self.qpos[address] = value

    def base(self, position, quat_wxyz):
        """The base body's pose in odom (m; w, x, y, z): its tree's free joint set to put it
        there (nothing for a base fixed to the world)."""
        if self._root_joint is None:
            return
        address = int(self.model.jnt_qposadr[self._root_joint])
        data = self.stage.data
        data.qpos[:] = self.qpos
        data.qpos[address:address + 7] = [0, 0, 0, 1, 0, 0, 0]
        mujoco.mj_kinematics(self.model, data)  # the base relative to its root
        inverse_pos, inverse_quat = np.empty(3), np.empty(4)
        mujoco.mju_negPose(inverse_pos, inverse_quat, data.xpos[self._base], data.xquat[self._base])
        root_pos, root_quat = np.empty(3), np.empty(4)
        mujoco.mju_mulPose(root_pos, root_quat, np.asarray(position, float),
                           np.asarray(quat_wxyz, float), inverse_pos, inverse_quat)
        self.qpos[address:address + 3] = root_pos
        self.qpos[address + 3:address + 7] = root_quat / np.linalg.norm(root_quat)

    def pose(self):
        self.stage.pose(self.qpos, self.stage.data.mocap_pos.copy(),
                        self.stage.data.mocap_quat.copy())


def _stamp(message):
    return message.header.stamp.sec + 1e-9 * message.header.stamp.nanosec


def _xyz(vector):
    return np.array([vector.x, vector.y, vector.z])


def _cloud_points(cloud):
    """(N, 3) x, y, z of a PointCloud2 of float32 x, y, z (12 bytes a point)."""
    return np.frombuffer(bytes(cloud.data), dtype='<f4').reshape(-1, 3).astype(float)


class _Cycle:
    """What the bag says of the current publish cycle and the state it keeps."""

    def __init__(self, stage, sim):
        self.legs = {leg: [np.zeros(3), np.zeros(3)] for leg in sim.legs}  # point, force
        self.frames = {topics.leg_frame_id(leg): leg for leg in sim.legs}
        self.wrenches = {topics.leg_wrench_topic(leg): leg for leg in sim.legs}
        self.plates = None
        self.zeta = sim.zeta
        self.bed = None if stage.bed is None else np.array(stage.bed.pristine)
        self.bed_changed = False


def render_bag(bag, sim, path, settings, log=None):
    """Render the rosbag2 folder `bag` of a run of `sim` (a Simulation of the scene it ran,
    not stepped) into the MP4 `path` as `settings` (VideoSettings) ask. Returns the frames
    written. Raises ValueError when the bag holds no /joint_states."""
    stage = Stage(sim, settings.width, settings.height, settings.sand_alpha)
    painter = FramePainter(stage, settings)
    poser = BagPoser(stage, sim.base_body)
    cycle = _Cycle(stage, sim)
    wanted = {topics.JOINT_STATES, topics.ODOM, topics.TF, topics.PLATES, topics.TERRAIN,
              topics.DIAGNOSTICS, *cycle.wrenches}
    state = {'time': None, 'next': 0, 'states': 0}
    try:
        with Mp4Writer(path, settings.width, settings.height, settings.fps) as writer:
            def flush():
                time = state['time']
                due = 0
                while state['next'] / settings.fps <= time + 1e-9:
                    state['next'] += 1
                    due += 1
                if not due:
                    return
                poser.pose()
                changed = cycle.bed_changed and stage.update_sand(cycle.bed)
                cycle.bed_changed = False
                frame = painter.paint(cycle.plates, [tuple(v) for v in cycle.legs.values()],
                                      overlay(time, cycle.zeta), changed)
                writer.write(frame, repeat=due)

            for topic, _, message in read_messages(bag, wanted):
                if topic == topics.TF:
                    for transform in message.transforms:
                        leg = cycle.frames.get(transform.child_frame_id)
                        if leg is not None:
                            cycle.legs[leg][0] = _xyz(transform.transform.translation)
                    continue
                if topic == topics.PLATES:
                    _read_plates(cycle, message)
                    continue
                stamp = _stamp(message) if topic != topics.DIAGNOSTICS else None
                if stamp is not None and topic == topics.JOINT_STATES:
                    if state['time'] is not None and stamp > state['time']:
                        flush()
                    state['time'] = stamp
                    state['states'] += 1
                    poser.joints(message.name, message.position)
                elif topic == topics.ODOM:
                    pose = message.pose.pose
                    o = pose.orientation
                    poser.base(_xyz(pose.position), (o.w, o.x, o.y, o.z))
                elif topic in cycle.wrenches:
                    cycle.legs[cycle.wrenches[topic]][1] = _xyz(message.wrench.force)
                elif topic == topics.TERRAIN and cycle.bed is not None:
                    _read_terrain(cycle, stage.bed, message)
                elif topic == topics.DIAGNOSTICS:
                    for status in message.status:
                        for item in status.values:
                            if item.key == 'zeta_n_per_cm3':
                                cycle.zeta = float(item.value)
            if state['time'] is None:
                raise ValueError(f'{bag}: no {topics.JOINT_STATES} in the bag: nothing to render')
            flush()
            frames = writer.frames
    finally:
        painter.close()
    if poser.missing and log is not None:
        log(f'joints in {topics.JOINT_STATES} that the model has not: '
            f'{", ".join(sorted(poser.missing))} (not drawn)')
    return frames


def _read_plates(cycle, message):
    """The plates of a /rft/plates MarkerArray (a SPHERE_LIST, or a DELETE: none)."""
    cycle.plates = None
    for marker in message.markers:
        if marker.points:
            positions = np.array([[p.x, p.y, p.z] for p in marker.points])
            rgba = np.array([[c.r, c.g, c.b, c.a] for c in marker.colors])
            cycle.plates = Plates(positions, rgba, np.full(len(positions), marker.scale.x))


def _read_terrain(cycle, bed, cloud):
    """Apply a /rft/terrain cloud (the whole bed, or its changed nodes) to the bed's heights."""
    points = _cloud_points(cloud)
    (x0, y0), (dx, dy) = bed.origin, bed.spacing
    i = np.rint((points[:, 0] - x0) / dx).astype(int)
    j = np.rint((points[:, 1] - y0) / dy).astype(int)
    ny, nx = cycle.bed.shape
    inside = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
    cycle.bed[j[inside], i[inside]] = points[inside, 2]
    cycle.bed_changed = True

