"""The RFT-SiM code's coupling loop, as a mode to compare against (`rft.coupling: paper`).

The authors' loop (Brown, Treers, Daltorio, RFT-SiM; github.com/Crab-Lab-CWRU/RFT-SiM) steps
MuJoCo and then computes the sand forces from what mjData holds after the step: the body
poses of the state the step started from (mj_step does not recompute them for the new
state) and velocities taken as finite differences of those poses between two steps. The
forces are applied during the next step. So the force acting from state S_(k+1) is the one
of state S_k: a one-step lag in both position and velocity. Each plate's force then passes
through an exponential moving average, F_s = alpha F + (1 - alpha) F_s(previous), whose
history a plate keeps when it leaves the sand (its next entry starts from the old value).

`PaperLoopEngine` is a `SandEngine` that steps so. What it shares with the exact coupling
(`SandEngine`): the plates, the sand surface, zeta and the force law
(`rft.force_law.plate_forces`, with the scene's normalisation: 'rft_sim' is the authors').
What it does differently, and only this: the lag, finite-difference plate velocities (each
plate's world position from its body's origin and orientation, differenced over one step),
the EMA with `low_velocity.ema_alpha` (0.5 in the authors' code, 0.1 in the paper's text)
or none (`low_velocity.method: none`), applied as a wrench at each body's centre of mass.
MuJoCo solves everything else as the model says (joint friction, limits, contacts).
It runs in numpy, not in the compiled kernels: it exists to reproduce the paper's numbers and
to show what exact coupling changes, not for speed.

Frames: world, z up; SI units (zeta in N/cm^3 at the interface, as everywhere).
"""
import mujoco
import numpy as np

from ..rft.force_law import plate_forces
from .engine import LowVelocity, SandEngine

#: Scene settings that make a scene's loop the authors' (`rft-sim validate` compares these
#: against the defaults): the lagged loop, their normalisation, their code's EMA factor.
PAPER_SETTINGS = {'rft.coupling': 'paper', 'rft.normalisation': 'rft_sim',
                  'rft.low_velocity.method': 'ema', 'rft.low_velocity.ema_alpha': 0.5}


class PaperLoopEngine(SandEngine):
    """RFT sand coupled as the RFT-SiM code couples it (see the module docstring).

    Arguments as `SandEngine`'s; low_velocity.method must be 'ema' (the authors') or 'none'
    (no smoothing), and the surface rigid (a plane, slope or grid; not deformable sand).
    Raises ValueError otherwise.
    """

    def __init__(self, model, data, body_plates, zeta, normalisation='treers',
                 low_velocity=LowVelocity(), **options):
        if low_velocity.method not in ('ema', 'none'):
            raise ValueError("the paper's coupling smooths with its moving average or not at "
                             "all: set rft.low_velocity.method to 'ema' or 'none' (got "
                             f"{low_velocity.method!r})")
        super().__init__(model, data, body_plates, zeta, normalisation=normalisation,
                         low_velocity=low_velocity, **options)
        self._normalisation_name = normalisation
        if self.deformable:
            raise ValueError("the paper's coupling has no deformable sand (its surface is "
                             'flat); use rft.coupling: exact')
        self._alpha = low_velocity.ema_alpha if low_velocity.method == 'ema' else 1.0
        counts = np.diff(self.plate_start)
        self._plate_body = np.repeat(self.body_ids, counts)  # body id of each plate
        self._plate_slot = np.repeat(np.arange(len(self.body_ids)), counts)
        self._positions = np.zeros((len(self.areas), 3))
        self._normals = np.zeros((len(self.areas), 3))
        self.forget_last_step()

    @property
    def kernels(self):
        """This engine's step runs in numpy, no compiled kernel (module docstring)."""
        return 'numpy (rft.coupling: paper), no compiled kernels'

    def forget_last_step(self):
        """As SandEngine's, and the loop's own memory: the last plate positions (so the
        next velocities are zero), the EMA history and the pending wrenches."""
        super().forget_last_step()
        n = len(self.areas)
        self._last_positions = None
        self._smoothed = np.zeros((n, 3))
        self._has_history = np.zeros(n, dtype=bool)
        self._pending = np.zeros((len(self.body_ids), 6))
        self._active = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))

    def step(self):
        """Advance the model one timestep, applying the wrenches computed after the last
        step, then compute the next step's from the poses mjData now holds."""
        model, data = self.model, self.data
        mujoco.mj_step1(model, data)
        data.xfrc_applied[self.body_ids] = self._pending
        self.body_wrenches[:] = self._pending
        mujoco.mj_step2(model, data)
        self._pending = self._lagged_wrenches()

    def _lagged_wrenches(self):
        """(nb, 6) [force; torque about the body's centre of mass] of each sand body, world
        axes, from the poses in mjData (the state the step started from), the plate
        velocities differenced against the last step's, and the EMA."""
        d = self.data
        positions, normals_all = self._positions, self._normals
        for i, body in enumerate(self.body_ids):  # plates of a body are contiguous
            start, end = self.plate_start[i], self.plate_start[i + 1]
            rotation = d.xmat[body].reshape(3, 3)
            positions[start:end] = self.local_pos[start:end] @ rotation.T + d.xpos[body]
            normals_all[start:end] = self.local_normal[start:end] @ rotation.T
        if self._last_positions is None:
            velocities = np.zeros_like(positions)
        else:
            velocities = (positions - self._last_positions) / self.model.opt.timestep
        self._last_positions = positions.copy()
        surface = self.surface.height(positions[:, 0], positions[:, 1])
        inside = np.flatnonzero(surface > positions[:, 2])
        wrenches = np.zeros((len(self.body_ids), 6))
        if not len(inside):
            self._active = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
            return wrenches
        p = positions[inside]
        normals = normals_all[inside]
        factor = (1.0 if self.zeta_map is None
                  else self.zeta_map.factor(p[:, 0], p[:, 1])[:, None])
        raw = factor * plate_forces(p, normals, self.areas[inside], velocities[inside],
                                    self.zeta, surface_height=surface[inside],
                                    normalisation=self._normalisation_name,
                                    dynamic=self.dynamic)
        old = self._smoothed[inside]
        force = np.where(self._has_history[inside, None],
                         self._alpha * raw + (1.0 - self._alpha) * old, raw)
        self._smoothed[inside] = force
        self._has_history[inside] = True
        slots, first = np.unique(self._plate_slot[inside], return_index=True)  # (sorted)
        lever = p - d.xipos[self._plate_body[inside]]
        wrenches[slots, :3] = np.add.reduceat(force, first)
        wrenches[slots, 3:] = np.add.reduceat(np.cross(lever, force), first)
        self._active = (p, force, self.areas[inside])
        return wrenches

    @property
    def plates_active(self):
        """Plates in the sand at the last force computation."""
        return len(self._active[2])

    def active_plates(self):
        """Plates in the sand at the last force computation: (positions (K, 3) m, forces
        (K, 3) N after the EMA, areas (K,) m^2), world frame; applied during the next step."""
        return tuple(a.copy() for a in self._active)
