"""The model the renderer draws: a copy of a simulation's model with the sand surface added
as geoms, a sky and a light, posed from the simulation's state.

The sand is drawn as the engine sees it (`sand.surface`): a plane, a slope (a tilted plane),
a height grid or MJCF hfield (an hfield of the grid's nodes over a plane at its lowest edge
node, where the grid's edge heights continue), and deformable sand (its bed as an hfield,
re-uploaded whenever the bed changed, over its base drawn as above, and coloured by how far
each node moved from the pristine surface: dug deeper blue, piled higher red, full at
CHANGE_FULL_SCALE_M, so footprints and craters show however shallow). A layer under another
is drawn LAYER_GAP lower so the two never fight for the same pixels. The model's own ground
that the sand replaces (floor planes and the sand's hfield geom, whose collisions the
simulation switched off) is hidden. The sand is a little transparent (its opacity
`sand_alpha`), so that feet and the plates under its surface show.

The sand geoms keep MuJoCo's default collision bits (the compiler discards geoms that
collide with nothing, as visual-only): the copy is posed (kinematics), never stepped, so
they meet nothing. Copying the model leaves its joints, bodies and qpos layout unchanged: a state of the
simulation (qpos, mocap poses) poses the copy as it is.
"""
import mujoco
import numpy as np

from ..sand.deformable import DeformableSand
from ..sand.surface import HeightGrid, Plane, Slope
from .drawn_model import DrawnModel

#: Dry sand's colour (RGB) and opacity (below 1: a foot and the plates under the surface
#: show through it; the scene's video.sand_alpha).
SAND_RGB, SAND_ALPHA = (0.87, 0.76, 0.55), 0.55
#: The two tones of the sand's checker, 25 cm squares: motion over a flat bed is seen.
CHECKER = ((0.90, 0.80, 0.60), (0.80, 0.69, 0.48))
CHECKER_M = 0.25
#: The sky's gradient, top to horizon (RGB), and the sun's direction (world, downwards).
SKY = ((0.55, 0.70, 0.90), (0.95, 0.95, 0.98))
SUN_DIRECTION = (-0.3, 0.4, -1.0)
#: m a layer under another is lowered by (deformable bed over its base).
LAYER_GAP = 0.002
#: m of travel an hfield of deformable sand leaves below its lowest and above its highest
#: node at the start (footprints, craters and piles within it are drawn to float32 precision).
BED_MARGIN_M = 0.3
#: m of height change drawn in full colour on deformable sand, and those colours (RGB).
CHANGE_FULL_SCALE_M = 0.01
DUG_RGB, PILED_RGB = (0.20, 0.30, 0.80), (0.85, 0.30, 0.20)
#: m of solid drawn under an hfield's lowest point.
HFIELD_BASE_M = 0.02
#: m between the grid lines a plane of sand is drawn with (MuJoCo's plane size[2]; the
#: checker is the texture's, and a directional light shades a plane evenly: finer grids only
#: cost vertices).
PLANE_GRID_M = 1.0
#: Samples per pixel of offscreen frames (MuJoCo's visual/quality/offsamples, 4 by default):
#: none. In Mesa's software renderer multisampling costs as much as the rest of a frame
#: (its 4 samples resolved on each read): edges show steps instead.
OFFSCREEN_SAMPLES = 0


def _ground_replaced(model):
    """Ids of the world's plane and hfield geoms that collide with nothing: the ground the
    simulation handed to the sand (its visual-only geoms were discarded when it compiled)."""
    world = model.body_weldid[model.geom_bodyid] == 0
    ground = np.isin(model.geom_type, (mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_HFIELD))
    off = (model.geom_contype == 0) & (model.geom_conaffinity == 0)
    return np.flatnonzero(world & ground & off)


def _up_quaternion(normal):
    """(w, x, y, z) turning +z onto the unit vector `normal`."""
    quat = np.empty(4)
    mujoco.mju_quatZ2Vec(quat, np.asarray(normal, float))
    return quat


class Stage(DrawnModel):
    """The drawn copy of `sim`'s model (a sim.simulation.Simulation, read, never changed),
    a DrawnModel that builds itself and redraws deformable sand from the simulation's bed.

    width, height: the largest frames it renders offscreen (pixels); sand_alpha: the sand's
    opacity (0, 1]. `model` and `data`: the
    copy; `pose(qpos, mocap_pos, mocap_quat)` poses it; `update_sand()` redraws deformable
    sand from a grid of heights; `robot_size` (m): the radius of the robot about its base at
    the start, `base_body` the base's id (the camera follows it)."""

    def __init__(self, sim, width=640, height=480, sand_alpha=SAND_ALPHA):
        self._sand_rgba = (*SAND_RGB, sand_alpha)
        spec = sim.description.spec.copy()
        # (the simulation's compile removed the visual-only geoms from the spec; without
        # this, compiling again would remove the sand's material, textures and sky too)
        spec.compiler.discardvisual = False
        spec.visual.global_.offwidth = max(int(width), spec.visual.global_.offwidth)
        spec.visual.global_.offheight = max(int(height), spec.visual.global_.offheight)
        spec.visual.quality.offsamples = OFFSCREEN_SAMPLES
        texture = spec.add_texture(name='rft_sand', type=mujoco.mjtTexture.mjTEXTURE_2D,
                                   builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
                                   rgb1=list(CHECKER[0]), rgb2=list(CHECKER[1]),
                                   width=64, height=64)
        material = spec.add_material(name='rft_sand', rgba=list(self._sand_rgba),
                                     texuniform=True, texrepeat=[1.0 / CHECKER_M] * 2)
        material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = texture.name
        # a sky (the transparent sand is seen over it) and a sun without shadows: in Mesa's
        # software renderer (llvmpipe) shadows cost about as much as the rest of a frame
        spec.add_texture(name='rft_sky', type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                         builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=list(SKY[0]),
                         rgb2=list(SKY[1]), width=64, height=64)
        spec.worldbody.add_light(name='rft_sun', type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
                                 dir=list(SUN_DIRECTION), castshadow=False,
                                 diffuse=[0.6] * 3, specular=[0.1] * 3)
        spec.visual.headlight.ambient = [0.35] * 3
        spec.visual.headlight.diffuse = [0.35] * 3
        self._grids = []  # (hfield name, HeightGrid, low, high)
        surface = sim.engine.surface
        if isinstance(surface, DeformableSand):
            self._add_surface(spec, surface.base, lowered=LAYER_GAP)
            rows, columns = surface.grid.shape
            bed_texture = spec.add_texture(name='rft_bed', type=mujoco.mjtTexture.mjTEXTURE_2D,
                                           width=columns, height=rows, nchannel=3)
            bed_texture.data = bytes(rows * columns * 3)  # (`update_sand` draws it)
            bed = spec.add_material(name='rft_bed', rgba=list(self._sand_rgba))
            bed.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = bed_texture.name
            self._add_grid(spec, surface, 'rft_bed', BED_MARGIN_M, material='rft_bed')
            self.bed = surface
        else:
            self._add_surface(spec, surface, lowered=0.0)
            self.bed = None
        self.model = spec.compile()
        self.model.geom_rgba[_ground_replaced(sim.model), 3] = 0.0
        for name, grid, low, high in self._grids:
            self._write_heights(name, grid.heights_as_seen() if grid is self.bed else grid.grid,
                                low, high)
        self.bed_hfield = self.bed_texture = None
        if self.bed is not None:
            self.bed_hfield = self.model.hfield('rft_bed').id
            self.bed_texture = self.model.texture('rft_bed').id
            self._write_colours(self.bed.heights_as_seen())
        self._bed_epoch = None if self.bed is None else self.bed.change_epoch
        self._under = 0  # nodes under bodies at the last redraw
        super().__init__(self.model, sim.model.body(sim.base_body).id, None, self.bed_hfield,
                         self.bed_texture, sim.data.qpos, sim.data.mocap_pos,
                         sim.data.mocap_quat)
        self.robot_size = self._robot_size()

    def _add_surface(self, spec, surface, lowered):
        """Geoms drawing a rigid `surface` (Plane, Slope or HeightGrid), `lowered` m."""
        if isinstance(surface, Plane):
            self._add_plane(spec, (0.0, 0.0, surface.level - lowered), (0.0, 0.0, 1.0))
        elif isinstance(surface, Slope):
            normal = np.array([-surface.gradient[0], -surface.gradient[1], 1.0])
            self._add_plane(spec, (0.0, 0.0, surface.level - lowered), normal / np.linalg.norm(normal))
        elif isinstance(surface, HeightGrid):
            edges = np.concatenate([surface.grid[0], surface.grid[-1], surface.grid[:, 0],
                                    surface.grid[:, -1]])
            self._add_plane(spec, (0.0, 0.0, float(edges.min()) - lowered - LAYER_GAP),
                            (0.0, 0.0, 1.0))
            self._add_grid(spec, surface, f'rft_grid{len(self._grids)}', 0.0, lowered)
        else:
            raise ValueError(f'cannot draw a sand surface of type {type(surface).__name__}')

    def _add_plane(self, spec, point, normal):
        geom = spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE,
                                       size=[0.0, 0.0, PLANE_GRID_M], pos=list(point),
                                       quat=list(_up_quaternion(normal)))
        self._dress(geom, 'rft_sand')

    def _dress(self, geom, material):
        """Give a sand geom its material and the material's colour: a geom colour of the
        model's default class (e.g. `<geom rgba=...>` in its `<default>`) would else replace
        the sand's colour and opacity."""
        geom.material = material  # (add_geom takes no material)
        geom.rgba = list(self._sand_rgba)

    def _add_grid(self, spec, grid, name, margin, lowered=0.0, material='rft_sand'):
        """An hfield geom drawing the HeightGrid `grid` `lowered` m, its heights' span
        widened by `margin` m both ways (the travel left to deformable sand)."""
        low = float(grid.grid.min()) - margin
        high = max(float(grid.grid.max()) + margin, low + 1e-3)
        rows, columns = grid.grid.shape
        data = np.zeros(rows * columns)
        data[0] = 1.0  # (the compiler normalises the data; `_write_heights` sets it)
        spec.add_hfield(name=name, nrow=rows, ncol=columns,
                        size=[grid.size[0] / 2, grid.size[1] / 2, high - low, HFIELD_BASE_M],
                        userdata=data.tolist())
        geom = spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname=name,
                                       pos=[grid.center[0], grid.center[1], low - lowered])
        self._dress(geom, material)
        self._grids.append((name, grid, low, high))

    def _write_heights(self, name, heights, low, high):
        """The hfield `name`'s data from `heights` (m, world z, rows along y) on (low, high)."""
        hfield = self.model.hfield(name)
        start, count = int(self.model.hfield_adr[hfield.id]), heights.size
        self.model.hfield_data[start:start + count] = np.clip(
            (heights.ravel() - low) / (high - low), 0.0, 1.0)

    def _write_colours(self, heights):
        """The bed's texture from its height changes (see module docstring); texture row 0
        is the bed's highest y (hfield row 0 its lowest)."""
        change = np.clip((np.asarray(heights) - self.bed.pristine) / CHANGE_FULL_SCALE_M,
                         -1.0, 1.0)[::-1, :, None]
        sand = np.array(CHECKER[0])
        rgb = (sand + np.maximum(-change, 0.0) * (np.array(DUG_RGB) - sand)
               + np.maximum(change, 0.0) * (np.array(PILED_RGB) - sand))
        start = int(self.model.tex_adr[self.bed_texture])
        self.model.tex_data[start:start + rgb.size] = (255 * rgb).astype(np.uint8).ravel()

    def update_sand(self, heights=None):
        """Redraw deformable sand: from `heights` (its grid's shape, m) or, without them, from
        the bed itself (`DeformableSand.heights_as_seen`: a body in the sand stands in its
        hole) when it changed or a body is in it. Returns whether it was redrawn (then the
        hfield `bed_hfield` and the texture `bed_texture` are to be uploaded again)."""
        if self.bed is None:
            return False
        if heights is None:
            under = self.bed.nodes_under_bodies
            if self.bed.change_epoch == self._bed_epoch and not (under or self._under):
                return False
            self._bed_epoch, self._under = self.bed.change_epoch, under
            heights = self.bed.heights_as_seen()
        name, _, low, high = self._grids[-1]
        self._write_heights(name, np.asarray(heights), low, high)
        self._write_colours(heights)
        return True

    def sand_drawing(self):
        """(hfield data, texture bytes) of deformable sand as drawn now (None without it),
        for a copy of the drawn model to draw (`DrawnModel.draw_sand`)."""
        if self.bed_hfield is None:
            return None
        return (self.model.hfield_data[self._hfield_slice()].copy(),
                self.model.tex_data[self._texture_slice()].copy())

    def __reduce__(self):
        """Pickled (for the video's painting process) as a DrawnModel posed as now: the
        drawn model without the simulation's sand, which that copy draws as it is given
        (`sand_drawing`)."""
        return DrawnModel, (self.model, self.base_body, self.robot_size, self.bed_hfield,
                            self.bed_texture, self.data.qpos.copy(),
                            self.data.mocap_pos.copy(), self.data.mocap_quat.copy())

    def _robot_size(self):
        """m: the farthest reach of the robot's geoms from its base body now (at least 5 cm)."""
        moving = self.model.body_weldid[self.model.geom_bodyid] != 0
        if not moving.any():
            return 0.05
        centre = self.data.xpos[self.base_body]
        reach = (np.linalg.norm(self.data.geom_xpos[moving] - centre, axis=1)
                 + self.model.geom_rbound[moving])
        return max(0.05, float(reach.max()))
