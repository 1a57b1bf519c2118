"""`DrawnModel`: the model a frame draws (a `stage.Stage`'s: the simulation's model with its
sand, sky and light), posed from a simulation's state, with deformable sand drawn as it is
given. What the video's painting process receives of a Stage (pickled), importing neither
the simulation nor the sand."""
import mujoco


class DrawnModel:
    """`model` (MjModel) posed in `data`; `base_body` (id) the base a camera follows and
    `robot_size` (m) the robot's radius about it; `bed_hfield` and `bed_texture`: the ids
    of deformable sand's hfield and texture (None without it). Posed at (qpos, mocap_pos,
    mocap_quat)."""

    def __init__(self, model, base_body, robot_size, bed_hfield, bed_texture, qpos,
                 mocap_pos, mocap_quat):
        self.model, self.base_body, self.robot_size = model, base_body, robot_size
        self.bed_hfield, self.bed_texture = bed_hfield, bed_texture
        self.data = mujoco.MjData(model)
        self.pose(qpos, mocap_pos, mocap_quat)

    def pose(self, qpos, mocap_pos=None, mocap_quat=None):
        """Put the model in the state `qpos` (and the mocap bodies' poses): positions, the
        centres of mass the tracking camera follows, cameras and lights."""
        self.data.qpos[:] = qpos
        if self.model.nmocap:
            self.data.mocap_pos[:] = mocap_pos
            self.data.mocap_quat[:] = mocap_quat
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)

    def draw_sand(self, drawing):
        """Draw deformable sand as `stage.Stage.sand_drawing` gave it: (hfield data,
        texture bytes)."""
        heights, colours = drawing
        self.model.hfield_data[self._hfield_slice()] = heights
        self.model.tex_data[self._texture_slice()] = colours

    def _hfield_slice(self):
        start = int(self.model.hfield_adr[self.bed_hfield])
        return slice(start, start + int(self.model.hfield_nrow[self.bed_hfield]
                                        * self.model.hfield_ncol[self.bed_hfield]))

    def _texture_slice(self):
        start = int(self.model.tex_adr[self.bed_texture])
        return slice(start, start + int(self.model.tex_width[self.bed_texture]
                                        * self.model.tex_height[self.bed_texture]
                                        * self.model.tex_nchannel[self.bed_texture]))
