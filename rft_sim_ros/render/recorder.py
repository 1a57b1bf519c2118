"""`VideoRecorder`: a `sim.runner.run_scene` recorder that renders a headless run into an MP4.

It is given the Simulation before the first step (`start`) and then every published state
(`record`), as the bag writer is. At each state that reaches the next frame's time (frames
at the video's rate, `VideoSettings.fps`, on sim time) it takes what a frame shows: the
pose (qpos, mocap poses), deformable sand when it changed (`stage.Stage.sand_drawing`), the
plates in the sand and the legs' ground forces of that state, the overlay's lines. A
state that reaches several frames' times (a publish rate below the video's) is repeated so
that the video plays in real time. The overlay gives sim time, zeta and each change of zeta
during the run (e.g. `--set-at`).

The frames are painted and encoded in a process of their own (`painting`), while the
simulation steps on: MuJoCo's renderer holds Python's GIL, so a thread would not overlap.
At most QUEUED_FRAMES wait for it; past that the run waits for the painter (a run never
gets ahead of its video by more, nor holds more). Closing the recorder waits for the frames
given and finishes the file; a run stopped early (Ctrl-C) leaves a playable video of what
was rendered, and so does a killed run up to its last whole second (`encoder`): the painter
whose parent is gone finishes the file.
"""
import os
import pickle
import subprocess
import sys
import time
from pathlib import Path

from .decorations import plates_from_forces
from .frames import VideoSettings
from .painting import DONE, FRAME_DONE, Frame
from .stage import Stage

#: Changes of zeta the overlay lists (the latest).
OVERLAY_CHANGES = 3
#: Frames given to the painter and not painted yet, at most (1.2 s of video at 25 fps).
QUEUED_FRAMES = 30


class PainterFailed(RuntimeError):
    """The painting process stopped with an error (its message) or died."""


class VideoRecorder:
    """Record a run of `scene` (SceneConfig) into the MP4 `path`, as `settings`
    (VideoSettings; default: the scene's `video` keys) ask. Once closed: `frames`, the
    frames written; `render_s` / `encode_s`, the painter's wall time rendering and encoding
    them, s; `frames_cpu_s` / `painter_cpu_s`, the CPU time of the painting process for the
    frames / in all (its start-up included; its renderer's threads included), s. `waited_s`:
    wall time the run waited for the painter (giving it frames while QUEUED_FRAMES were not
    painted or its pipe was full, and for the last ones when closing), s."""

    wants_plates = False  # (it reads the active plates itself, at its own rate)

    def __init__(self, path, scene, settings=None):
        self.path = path
        self.settings = settings or VideoSettings.from_scene(scene)
        self._stage = self._sim = self._painter = None
        self._next_frame = 0  # index of the next frame to take
        self._queued = 0  # frames given to the painter and not painted yet
        self._zeta = None
        self._changes = []
        self.frames = 0
        self.render_s = self.encode_s = self.frames_cpu_s = self.painter_cpu_s = 0.0
        self.waited_s = 0.0

    def start(self, sim):
        """Called by run_scene with the Simulation before its first step: starts the
        painting process with a copy of the drawn model."""
        self._sim = sim
        self._stage = Stage(sim, self.settings.width, self.settings.height,
                            self.settings.sand_alpha)
        package_root = str(Path(__file__).resolve().parents[2])  # (the painter imports it)
        paths = [package_root, *filter(None, os.environ.get('PYTHONPATH', '').split(os.pathsep))]
        self._painter = subprocess.Popen(
            [sys.executable, '-m', 'rft_sim_ros.render.painting'], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, env={**os.environ, 'PYTHONPATH': os.pathsep.join(paths)},
            start_new_session=True)  # (a Ctrl-C at the terminal: for the run to handle)
        self._give((self._stage, self.settings, str(self.path)))

    def record(self, state):
        """Give the painter the frames whose time `state` (SimState) reached."""
        due = 0
        while self._next_frame / self.settings.fps <= state.time + 1e-9:
            self._next_frame += 1
            due += 1
        self._note_zeta(state)
        if due:
            frame = self._frame(state, due)
            started = time.perf_counter()
            if self._queued >= QUEUED_FRAMES:
                self._painted(self._queued - QUEUED_FRAMES + 1)
            self._give(frame)
            self._queued += 1
            self.waited_s += time.perf_counter() - started

    def _note_zeta(self, state):
        if self._zeta is not None and state.zeta != self._zeta:
            self._changes.append(f't = {state.time:.2f} s: zeta {self._zeta:g} -> '
                                 f'{state.zeta:g} N/cm^3')
        self._zeta = state.zeta

    def _frame(self, state, repeat):
        """What the painter needs for one frame of `state`."""
        sim, stage = self._sim, self._stage
        plates = None
        if self.settings.plates:
            positions, forces, areas = sim.engine.active_plates()
            plates = plates_from_forces(positions, forces, areas, state.zeta, stage.robot_size)
        return Frame(qpos=sim.data.qpos.copy(), mocap_pos=sim.data.mocap_pos.copy(),
                     mocap_quat=sim.data.mocap_quat.copy(),
                     sand=stage.sand_drawing() if stage.update_sand() else None,
                     plates=plates, legs=[(leg.point, leg.force) for leg in state.legs],
                     lines=overlay(state.time, state.zeta, self._changes), repeat=repeat)

    def _give(self, item):
        try:
            pickle.dump(item, self._painter.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            self._painter.stdin.flush()
        except (BrokenPipeError, OSError):
            self._failed()

    def _painted(self, count):
        """Wait until `count` more frames are painted."""
        for _ in range(count):
            answer = self._painter.stdout.read(1)
            if answer != FRAME_DONE:
                self._failed(answer)
            self._queued -= 1

    def _failed(self, answer=b''):
        """Raise PainterFailed with the painter's error (it answered `answer`, not a frame)."""
        painter, self._painter = self._painter, None
        result = self._answer(painter, answer)
        raise PainterFailed(f'video: {result.get("error", "the painting process died")}')

    @staticmethod
    def _answer(painter, answer):
        """The painter's pickled answer after DONE (`answer` read of it so far), once it
        ended; {} where it died without one."""
        try:
            painter.stdin.close()
        except OSError:
            pass
        rest = painter.stdout.read()
        painter.wait()
        data = answer + rest
        while data.startswith(FRAME_DONE):
            data = data[1:]
        return pickle.loads(data[1:]) if data.startswith(DONE) else {}

    def close(self):
        """Wait for the frames given and finish the video (a run that never started leaves
        no file). Raises PainterFailed where the painter failed."""
        if self._painter is None:
            return
        started = time.perf_counter()
        self._give(None)
        painter, self._painter = self._painter, None
        result = self._answer(painter, b'')
        self.waited_s += time.perf_counter() - started
        if 'frames' not in result or 'error' in result:
            raise PainterFailed(f'video: {result.get("error", "the painting process died")}')
        self.frames = result['frames']
        self.render_s, self.encode_s = result['render_s'], result['encode_s']
        self.frames_cpu_s, self.painter_cpu_s = result['frames_cpu_s'], result['cpu_s']


def overlay(time_s, zeta, changes=()):
    """The overlay's (label, value) lines: sim time, zeta and the latest changes of zeta."""
    return [('t', f'{time_s:.2f} s'), ('zeta', f'{zeta:g} N/cm^3'),
            *(('', change) for change in changes[-OVERLAY_CHANGES:])]
