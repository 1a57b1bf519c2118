"""Frames of a `stage.Stage` rendered offscreen (`gl.offscreen_context`) with MuJoCo's own
renderer (mjv_updateScene, mjr_render, mjr_overlay, mjr_readPixels): the camera a
`VideoSettings` asks for, the plates and force arrows (`decorations`) and a text overlay.

Cameras: 'follow' tracks the robot's base body (MuJoCo's tracking camera on its subtree's
centre of mass) from FOLLOW_DISTANCE robot sizes; 'fixed' looks from where 'follow' starts
and stays; any other name is one of the model's own cameras.
"""
from dataclasses import dataclass

import mujoco
import numpy as np

from . import decorations
from .gl import offscreen_context

#: Robot sizes (`Stage.robot_size`) between a following camera and the robot's base.
FOLLOW_DISTANCE = 3.0
#: The following camera's heading and pitch (deg): from behind and to the left of +x, above.
FOLLOW_AZIMUTH, FOLLOW_ELEVATION = 135.0, -25.0
#: Extra geoms a frame may add to the model's: plates and arrows.
EXTRA_GEOMS = 6000
#: Camera names that are not the model's own.
CAMERAS = ('follow', 'fixed')


@dataclass(frozen=True)
class VideoSettings:
    """A video's frames: fps (frames per second of sim time), width and height (pixels,
    even: H.264 in yuv420p), camera ('follow', 'fixed' or a camera of the model), whether
    the force arrows and the plates are drawn, and the sand's opacity (0, 1]."""
    fps: float = 25.0
    width: int = 640
    height: int = 480
    camera: str = 'follow'
    forces: bool = True
    plates: bool = True
    sand_alpha: float = 0.55

    @classmethod
    def from_scene(cls, scene):
        """The settings of a SceneConfig's `video` keys (scenes/schema.py)."""
        values = scene.values
        return cls(fps=values['video.fps'], width=values['video.width'],
                   height=values['video.height'], camera=values['video.camera'],
                   forces=values['video.forces'], plates=values['video.plates'],
                   sand_alpha=values['video.sand_alpha'])


def camera_for(stage, name):
    """The MjvCamera named `name` (see module docstring) for `stage`; raises ValueError
    naming the model's cameras for an unknown name."""
    camera = mujoco.MjvCamera()
    model = stage.model
    if name in CAMERAS:
        camera.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        camera.trackbodyid = stage.base_body
        camera.distance = FOLLOW_DISTANCE * stage.robot_size
        camera.azimuth, camera.elevation = FOLLOW_AZIMUTH, FOLLOW_ELEVATION
        if name == 'fixed':
            camera.type = mujoco.mjtCamera.mjCAMERA_FREE
            camera.lookat[:] = stage.data.subtree_com[stage.base_body]
        return camera
    names = [model.camera(i).name for i in range(model.ncam)]
    if name not in names:
        raise ValueError(f'video.camera {name!r}: not {" or ".join(CAMERAS)}, nor a camera of '
                         'the model' + (f' ({", ".join(n for n in names if n)})' if any(names)
                                        else ' (it has none)'))
    camera.type = mujoco.mjtCamera.mjCAMERA_FIXED
    camera.fixedcamid = names.index(name)
    return camera


class FramePainter:
    """Renders frames of `stage` as `settings` (VideoSettings) asks; `close()` frees the
    OpenGL context. Raises gl.RenderingUnavailable when no context can be made."""

    def __init__(self, stage, settings):
        self.stage, self.settings = stage, settings
        self.camera = camera_for(stage, settings.camera)
        model = stage.model
        self._gl = offscreen_context(settings.width, settings.height)
        try:
            self.scene = mujoco.MjvScene(model, maxgeom=model.ngeom + EXTRA_GEOMS)
            self.option = mujoco.MjvOption()
            self.option.geomgroup[:] = 1  # collision geoms too (a model's group 3, hidden
            # by default): the sand meets them
            scale = mujoco.mjtFontScale.mjFONTSCALE_100 if settings.height < 720 else \
                mujoco.mjtFontScale.mjFONTSCALE_150
            self._context = mujoco.MjrContext(model, scale)
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._context)
        except Exception:
            self._gl.free()
            raise
        self.viewport = mujoco.MjrRect(0, 0, settings.width, settings.height)
        self._pixels = np.empty((settings.height, settings.width, 3), dtype=np.uint8)
        self.weight = decorations.robot_weight(model)

    def paint(self, plates=None, legs=(), lines=(), sand_changed=False):
        """An (height, width, 3) uint8 RGB frame of the stage as posed now.

        plates: decorations.Plates (drawn when the settings ask). legs: (point, force)
        pairs, m and N, world (arrows when the settings ask). lines: (label, value) texts of
        the overlay, top left. sand_changed: deformable sand was redrawn (`Stage.update_sand`)."""
        model, scene, context = self.stage.model, self.scene, self._context
        self._gl.make_current()
        if sand_changed:
            mujoco.mjr_uploadHField(model, context, self.stage.bed_hfield)
            mujoco.mjr_uploadTexture(model, context, self.stage.bed_texture)
        mujoco.mjv_updateScene(model, self.stage.data, self.option, None, self.camera,
                               mujoco.mjtCatBit.mjCAT_ALL, scene)
        if plates is not None and self.settings.plates:
            decorations.add_plates(scene, plates)
        if legs and self.settings.forces:
            points, forces = zip(*legs)
            decorations.add_force_arrows(scene, points, forces, self.weight,
                                         self.stage.robot_size)
        mujoco.mjr_render(self.viewport, scene, context)
        if lines:
            mujoco.mjr_overlay(mujoco.mjtFont.mjFONT_NORMAL, mujoco.mjtGridPos.mjGRID_TOPLEFT,
                               self.viewport, '\n'.join(label for label, _ in lines),
                               '\n'.join(value for _, value in lines), context)
        mujoco.mjr_readPixels(self._pixels, None, self.viewport, context)
        return self._pixels[::-1]  # (OpenGL's rows run bottom up)

    def close(self):
        """Free the renderer's OpenGL resources (the painter cannot paint after)."""
        if self._gl is not None:
            self._gl.make_current()
            self._context.free()
            self._gl.free()
            self._gl = None
