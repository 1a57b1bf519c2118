"""`VideoRecorder`: a `sim.runner.run_scene` recorder that renders a headless run into an MP4.

It is given the Simulation before the first step (`start`) and then every published state
(`record`), as the bag writer is; at each state that reaches the next frame's time (frames
at the video's rate, `VideoSettings.fps`, on sim time) it poses its `stage.Stage` from the
simulation's qpos, redraws deformable sand when it changed, and renders one frame with the
plates in the sand and the legs' ground forces of that state. A state that reaches several
frames' times (a publish rate below the video's) is repeated so that the video plays in
real time. The overlay gives sim time, zeta and each change of zeta during the run (e.g.
`--set-at`). Closing it finishes the file; a run stopped early leaves a playable video of
what was rendered (`encoder`).
"""
import time

from .decorations import plates_from_forces
from .encoder import Mp4Writer
from .frames import FramePainter, VideoSettings
from .stage import Stage

#: Changes of zeta the overlay lists (the latest).
OVERLAY_CHANGES = 3


class VideoRecorder:
    """Record a run of `scene` (SceneConfig) into the MP4 `path`, as `settings`
    (VideoSettings; default: the scene's `video` keys) ask. `frames`: frames written;
    `render_s` / `encode_s`: wall time spent rendering and encoding them, s."""

    wants_plates = False  # (it reads the active plates itself, at its own rate)

    def __init__(self, path, scene, settings=None):
        self.path = path
        self.settings = settings or VideoSettings.from_scene(scene)
        self._painter = self._writer = self._sim = None
        self._next_frame = 0  # index of the next frame to write
        self._zeta = None
        self._changes = []
        self.render_s = self.encode_s = 0.0

    @property
    def frames(self):
        return 0 if self._writer is None else self._writer.frames

    def start(self, sim):
        """Called by run_scene with the Simulation before its first step."""
        self._sim = sim
        stage = Stage(sim, self.settings.width, self.settings.height)
        self._painter = FramePainter(stage, self.settings)
        self._writer = Mp4Writer(self.path, self.settings.width, self.settings.height,
                                 self.settings.fps)

    def record(self, state):
        """Render the frames whose time `state` (SimState) reached."""
        due = 0
        while self._next_frame / self.settings.fps <= state.time + 1e-9:
            self._next_frame += 1
            due += 1
        self._note_zeta(state)
        if due:
            started = time.perf_counter()
            frame = self._render(state)
            rendered = time.perf_counter()
            self._writer.write(frame, repeat=due)
            self.render_s += rendered - started
            self.encode_s += time.perf_counter() - rendered

    def _note_zeta(self, state):
        if self._zeta is not None and state.zeta != self._zeta:
            self._changes.append(f't = {state.time:.2f} s: zeta {self._zeta:g} -> '
                                 f'{state.zeta:g} N/cm^3')
        self._zeta = state.zeta

    def _render(self, state):
        sim, painter = self._sim, self._painter
        stage = painter.stage
        stage.pose(sim.data.qpos, sim.data.mocap_pos, sim.data.mocap_quat)
        plates = None
        if self.settings.plates:
            positions, forces, areas = sim.engine.active_plates()
            plates = plates_from_forces(positions, forces, areas, state.zeta, stage.robot_size)
        legs = [(leg.point, leg.force) for leg in state.legs]
        return painter.paint(plates, legs, overlay(state.time, state.zeta, self._changes),
                             sand_changed=stage.update_sand())

    def close(self):
        """Finish the video (a run that never started leaves no file)."""
        try:
            if self._writer is not None:
                self._writer.close()
        finally:
            if self._painter is not None:
                self._painter.close()


def overlay(time_s, zeta, changes=()):
    """The overlay's (label, value) lines: sim time, zeta and the latest changes of zeta."""
    return [('t', f'{time_s:.2f} s'), ('zeta', f'{zeta:g} N/cm^3'),
            *(('', change) for change in changes[-OVERLAY_CHANGES:])]
