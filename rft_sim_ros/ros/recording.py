"""Record a headless run (`rft_sim_ros.sim.runner.run_scene`) into a rosbag2 (MCAP) folder.

`BagRecorder` is a run_scene recorder: every state it is given is one publish cycle of the
node (the same `BagWriter.write_state` messages), the first the initial state at sim time 0
that the node publishes at its first tick (with the whole sand surface and /diagnostics,
its real-time factor nan: nothing measured yet), and /diagnostics follows the node's rule
(`rft_sim_ros.ros.diagnostics`) counted in sim seconds, and the sand surface follows the
node's rule (`rft_sim_ros.ros.terrain`, at its default rate), so a headless bag holds the topics
and types that `ros2 bag record` of the node holds. If the run diverges, a last /diagnostics
(level ERROR, the reason as message) is stamped with the last recorded state's time. The
cycles are written in batches (`BATCH`); the bag is complete once the recorder is closed.
"""
import time

from rft_sim_ros.ros.bag import BagWriter
from rft_sim_ros.ros.diagnostics import DiagnosticsSchedule, status_key
from rft_sim_ros.ros.messages import RunStatus
from rft_sim_ros.ros.terrain import TerrainFeed

#: Publish cycles written to the bag together. Between two cycles the simulation's steps
#: push the writer's code and data out of the CPU caches: the hexapod's cycles written one by
#: one took 31 ms of its 0.55 s run, in batches of 50 about 18 ms. What is written is decided
#: when each state is recorded (the surface's changes, /diagnostics with its real-time
#: factor); `close` writes the rest.
BATCH = 50


class BagRecorder:
    """Write a run of `scene` (SceneConfig) into a new rosbag2 folder `path` (created when the
    run starts).

    plates: record /rft/plates (active plate markers). diagnostics_period_s: sim seconds
    between /diagnostics. clock: wall time, s, for the reported real-time factor.
    """

    def __init__(self, path, scene, *, plates=False, diagnostics_period_s=1.0,
                 clock=time.perf_counter):
        self.wants_plates = bool(plates)
        self._scene = scene.name
        self._path = path
        self._writer = None  # opened by start(), once the Simulation knows its legs
        self._schedule = DiagnosticsSchedule(diagnostics_period_s)
        self._clock = clock
        self._sim = None
        self._terrain = None
        self._started = None
        self._last = None
        self._pending = []

    def start(self, sim):
        """Called by run_scene with the Simulation before its first step."""
        self._sim = sim
        self._terrain = TerrainFeed(sim.engine.surface)
        self._writer = BagWriter(self._path, list(sim.legs), plates=self.wants_plates,
                                 terrain=self._terrain.active, sensors=sim.sensors.layout)
        self._started = (sim.time, self._clock())

    def _status(self, state):
        sim_start, wall_start = self._started
        wall = self._clock() - wall_start
        rejected = self._sim.commands.rejections if self._sim.commands is not None else {}
        return RunStatus(scene=self._scene,
                         real_time_factor=(state.time - sim_start) / wall
                         if wall > 0 and state.time > sim_start else float('nan'),
                         stable=self._sim.diverged is None, problem=self._sim.diverged or '',
                         commands_rejected=rejected, outcome=self._sim.outcome(),
                         kernels=self._sim.kernels)

    def record(self, state):
        """One publish cycle of `state` (SimState), plus the sand surface and /diagnostics
        when due: decided now, from the simulation as it is now; written in batches of
        BATCH cycles."""
        update = self._terrain.update(state.time)
        key = status_key(state.zeta, self._sim.diverged is None, False,  # (never paused)
                         self._sim.down)
        status = self._status(state) if self._schedule.due(state.time, key) else None
        self._pending.append((state, update, status))
        self._last = state
        if len(self._pending) >= BATCH:
            self._flush()

    def _flush(self):
        """Write the pending cycles in time order: the states in runs, each run up to a
        state whose surface change or /diagnostics follows it."""
        states = []
        for state, update, status in self._pending:
            states.append(state)
            if update is not None or status is not None:
                self._writer.write_states(states)
                states = []
                if update is not None:
                    self._writer.write_terrain(update)
                if status is not None:
                    self._writer.write_diagnostics(state, status)
        self._writer.write_states(states)
        self._pending.clear()

    def close(self):
        """Record the surface's last changes (whatever the rate: the bag ends with the final
        surface) and a divergence on /diagnostics, then finish the bag (an empty one if the
        run never started)."""
        if self._writer is None:
            self._writer = BagWriter(self._path, [], plates=self.wants_plates)
        self._flush()
        if self._last is not None:
            update = self._terrain.update(self._last.time, due=True)
            if update is not None:
                self._writer.write_terrain(update)
        if self._sim is not None and self._sim.diverged and self._last is not None:
            self._writer.write_diagnostics(self._last, self._status(self._last))
        self._writer.close()
