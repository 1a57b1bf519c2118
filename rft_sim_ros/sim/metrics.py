"""Metrics every run reports, whatever its scenario: how the base moved, how deep each sand
body went, how hard the sand pushed on each leg, and whether the run stayed stable. Each
covers the whole run, from the initial state on; a scenario's own metrics use other names
(the runner warns where one does not).

`GenericMetrics` is fed the SimState snapshots of a run (at the publish rate) and the
Simulation they came from; `result()` gives (SI units, world frame = odom, z up):

  base_displacement_m          |base position at the end - at the start| (3D);
  base_displacement_xyz_m      the same as a vector;
  base_mean_speed_mps          path length of the base positions sampled from the initial
                               state on, / elapsed time;
  final_speed_mps              |base linear velocity| at the last sample;
  max_sinkage_m_<body>         deepest point of the sand body's plates below the sand
                               surface over it (sand bodies only: the other bodies'
                               depths are in the summary's `outcome`, sim/outcome.py);
  mean_stance_sinkage_m_<body> that sinkage averaged over the samples where it is > 0 (the
                               body in the sand; 0 if it never was);
  mean_force_z_N_<leg>, peak_force_z_N_<leg>
                               vertical sand force on the leg (its sand bodies and the
                               other bodies of its branch), mean and largest, over the
                               whole run (a drop's landing included);
  stable                       the run ended without diverging (set by the runner).
"""
import numpy as np


def _stacked_plates(positions, plate_start):
    """(bodies, 4, P) body-frame plate positions (m) in homogeneous coordinates: the rows x,
    y, z, 1 of each body's plates (`positions[plate_start[b]:plate_start[b + 1]]`); a body
    with fewer than P plates repeats its first plate, which changes no maximum over them."""
    counts = np.diff(plate_start)
    stacked = np.ones((len(counts), 4, int(counts.max(initial=1))))
    for b, (start, count) in enumerate(zip(plate_start[:-1], counts)):
        body = positions[start:start + count]
        stacked[b, :3, :count] = body.T
        stacked[b, :3, count:] = body[:1].T
    return stacked


class GenericMetrics:
    """Accumulates the generic metrics of one run (see module docstring)."""

    def __init__(self, sim):
        engine = sim.engine
        count = len(sim.sand_bodies)  # (the engine's first bodies; then the other bodies,
        # which the outcome watches: sim/outcome.py)
        self._surface = engine.surface
        self._bodies = engine.body_names[:count]
        self._body_ids = engine.body_ids[:count]
        self._plates = _stacked_plates(engine.local_pos, engine.plate_start[:count + 1])
        # scratch, reused at every sample: [rotation | position] per body, world positions
        # (bodies, 3, P) and depths (bodies, P) of the plates
        self._poses = np.empty((len(self._body_ids), 3, 4))
        self._world = np.empty((len(self._body_ids), 3, self._plates.shape[2]))
        self._below = np.empty((len(self._body_ids), self._plates.shape[2]))
        self._legs = None
        self._times, self._base, self._speed, self._depth, self._force_z = [], [], [], [], []

    def depths(self, data):
        """(bodies,) m: deepest plate of each sand body below the sand surface over it (0 if
        none is below)."""
        # all bodies in one stacked matrix product of their poses and homogeneous plate
        # positions, rows x, y, z of each body's plates contiguous (4.5x cheaper than a
        # rotation and a translation per body; sampled at the publish rate)
        ids, poses = self._body_ids, self._poses
        poses[:, :, :3] = data.xmat[ids].reshape(-1, 3, 3)
        poses[:, :, 3] = data.xpos[ids]
        world = np.matmul(poses, self._plates, out=self._world)
        below = np.subtract(self._surface.height(world[:, 0], world[:, 1]), world[:, 2],
                            out=self._below)
        return np.maximum(np.maximum.reduce(below, axis=1), 0.0)

    @property
    def latest_depths(self):
        """(bodies,) m: `depths` at the latest snapshot observed."""
        return self._depth[-1]

    def observe(self, sim, state):
        """Record one snapshot `state` (SimState) of `sim`."""
        self._legs = [leg.name for leg in state.legs]
        self._times.append(state.time)
        self._base.append(state.base_position)
        self._speed.append(state.base_speed)
        self._depth.append(self.depths(sim.data))
        self._force_z.append([leg.force[2] for leg in state.legs])

    def result(self, stable):
        """{metric: value} (module docstring); only `stable` before any snapshot."""
        metrics = {'stable': bool(stable)}
        if not self._times:
            return metrics
        base = np.array(self._base)
        elapsed = self._times[-1] - self._times[0]
        path = float(np.linalg.norm(np.diff(base, axis=0), axis=1).sum())
        displacement = base[-1] - base[0]
        metrics.update({
            'base_displacement_m': float(np.linalg.norm(displacement)),
            'base_displacement_xyz_m': [float(v) for v in displacement],
            'base_mean_speed_mps': path / elapsed if elapsed > 0 else 0.0,
            'final_speed_mps': self._speed[-1],
        })
        depth = np.array(self._depth)
        for i, body in enumerate(self._bodies):
            touching = depth[:, i] > 0
            metrics[f'max_sinkage_m_{body}'] = float(depth[:, i].max())
            metrics[f'mean_stance_sinkage_m_{body}'] = (
                float(depth[touching, i].mean()) if touching.any() else 0.0)
        force_z = np.array(self._force_z).reshape(len(self._times), -1)
        for i, leg in enumerate(self._legs):
            metrics[f'mean_force_z_N_{leg}'] = float(force_z[:, i].mean())
            metrics[f'peak_force_z_N_{leg}'] = float(force_z[:, i].max())
        return metrics
