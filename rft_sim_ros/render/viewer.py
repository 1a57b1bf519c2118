"""MuJoCo's interactive viewer on a running simulation: `LiveView` (passive viewer, the
caller steps) and `view` (`rft-sim view`: steps a scene at real time until the window
closes).

The viewer shows a `stage.Stage` (the sand drawn as in the videos, the plates and force
arrows added to its user scene) posed from the simulation after each sync. What the mouse
does in the window acts on the simulation: a body dragged (double-click it, then Ctrl +
right drag) gets the viewer's perturbation force, applied to the simulation as generalised
forces (qfrc_applied, which the sand's implicit solve takes in). Keys: space pauses and
resumes, right arrow steps one publish period while paused.
"""
import os
import time

import mujoco
import numpy as np

from . import decorations
from .stage import Stage

#: glfw key codes of space and the right arrow.
KEY_SPACE, KEY_RIGHT = 32, 262


class ViewerUnavailable(ValueError):
    """The viewer cannot open here (no display); the message says so in one line."""


def check_display():
    """Raise ViewerUnavailable unless a display is there for a window."""
    if not (os.environ.get('DISPLAY') or os.environ.get('WAYLAND_DISPLAY')):
        raise ViewerUnavailable('cannot open the viewer: no display (DISPLAY and '
                                'WAYLAND_DISPLAY unset); on a headless machine record a video '
                                'instead (rft-sim run --video)')


class LiveView:
    """A passive MuJoCo viewer window on `sim` (a Simulation); `show()` after stepping.
    `paused` and `step_requested` follow the keys; `is_running()` until the window closes."""

    def __init__(self, sim, forces=True, plates=True):
        check_display()
        import mujoco.viewer
        self.sim, self.forces, self.plates = sim, forces, plates
        self.stage = Stage(sim)
        self.paused = self.step_requested = False
        self._weight = decorations.robot_weight(sim.model)
        self._qfrc = np.zeros(sim.model.nv)
        try:
            self.handle = mujoco.viewer.launch_passive(self.stage.model, self.stage.data,
                                                       key_callback=self._key)
        except Exception as error:  # (glfw cannot open a window on this display)
            raise ViewerUnavailable(f'cannot open the viewer: {" ".join(str(error).split())}'
                                    ) from None

    def _key(self, key):
        if key == KEY_SPACE:
            self.paused = not self.paused
        elif key == KEY_RIGHT:
            self.step_requested = True

    def is_running(self):
        return self.handle.is_running()

    def show(self, state=None):
        """Pose the window's model from the simulation, the plates and, with `state`
        (SimState), the legs' force arrows; hand the viewer's perturbation to the
        simulation."""
        sim, stage, handle = self.sim, self.stage, self.handle
        with handle.lock():
            self._perturb()
            stage.pose(sim.data.qpos, sim.data.mocap_pos, sim.data.mocap_quat)
            changed = stage.update_sand()
            scene = handle.user_scn
            scene.ngeom = 0
            if self.plates:
                positions, forces, areas = sim.engine.active_plates()
                decorations.add_plates(scene, decorations.plates_from_forces(
                    positions, forces, areas, sim.zeta, stage.robot_size))
            if self.forces and state is not None:
                decorations.add_force_arrows(scene, [leg.point for leg in state.legs],
                                             [leg.force for leg in state.legs], self._weight,
                                             stage.robot_size)
        if changed:
            handle.update_hfield(stage.bed_hfield)
            handle.update_texture(stage.bed_texture)
        handle.sync()

    def _perturb(self):
        """The viewer's perturbation forces on the drawn bodies, as generalised forces on
        the simulation's (same bodies, same ids)."""
        sim, applied = self.sim, self.stage.data.xfrc_applied
        self._qfrc[:] = 0.0
        for body in np.flatnonzero(np.any(applied != 0.0, axis=1)):
            mujoco.mj_applyFT(sim.model, sim.data, applied[body, :3], applied[body, 3:],
                              sim.data.xipos[body], int(body), self._qfrc)
        sim.data.qfrc_applied[:] = self._qfrc

    def close(self):
        self.handle.close()


def view(sim, real_time_factor=1.0, log=None, until=None):
    """Run `sim` in a LiveView at `real_time_factor` (sim s per wall s; slower where the
    machine cannot keep up) until the window closes (or `until` s of sim time, for tests).
    Returns the sim time reached, s."""
    from ..sim.publishing import PublishSchedule
    live = LiveView(sim)
    period = PublishSchedule(sim.scene.publish_rate, sim.timestep)
    cycle, done = 1, 0
    state = sim.state()
    started, sim_start = time.perf_counter(), sim.time
    try:
        while live.is_running() and (until is None or sim.time < until):
            if live.paused and not live.step_requested:
                live.show(state)
                time.sleep(0.02)
                started, sim_start = time.perf_counter(), sim.time  # (real time from here)
                continue
            live.step_requested = False
            steps = period.end_step(cycle) - done
            sim.step(steps)
            done += steps
            cycle += 1
            state = sim.state()
            live.show(state)
            ahead = (sim.time - sim_start) / real_time_factor - (time.perf_counter() - started)
            if ahead > 0:
                time.sleep(ahead)
    finally:
        live.close()
    return sim.time
