"""Built-in gaits: functions of sim time that return joint position targets.

A gait maps sim time t (s) to position targets (rad) for the joints of a set of
lateral-plane knee-ankle legs (`LateralLegs`), as an array in `joint_names` order (knee,
ankle, leg by leg; for the hexapod that is `rft_sim_ros.scenes.hexapod.JOINT_NAMES`) or as a
name -> value dict. numpy, and the compiled kernels of `gait_kernels`: the leg geometry is
passed in (defaults: the bundled hexapod).

Gaits (`make_gait(name, ...)`):
- 'none'   `StandGait`: hold the neutral stance.
- 'tripod' `TripodGait`: the alternating tripod of RFT-SiM; walks sideways, towards +y of
  base_link (the published gait's heading of 90 deg).
"""
import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from rft_sim_ros import prebuilt
from rft_sim_ros.kernel_names import FOOT_PATH, TRIPOD_TARGETS
from rft_sim_ros.scenes import hexapod
from rft_sim_ros.scenes.leg_kinematics import LateralLegs


def _joint_names(legs):
    return tuple(f'{leg}_{joint}' for leg in legs.names for joint in ('knee', 'ankle'))


def smoothstep(u):
    """0 for u <= 0, 1 for u >= 1, 3u^2 - 2u^3 between: continuous value and slope."""
    u = min(max(u, 0.0), 1.0)
    return u * u * (3.0 - 2.0 * u)


class GaitClock:
    """Phases and ramp of a periodic gait: leg phases from frequency_hz, start_time_s and
    the legs' phase offsets `_offsets` (cycles), stroke scale from ramp_time_s; checks of
    the values every such gait has."""

    def check_values(self, *others):
        """Raise ValueError unless frequency_hz > 0, 0 < stance_fraction < 1, step_height_m
        and ramp_time_s >= 0, and these, step_length_m, start_time_s and the attributes
        named in `others` are finite; then makes each a float (as the gaits' kernels take
        them: `prebuilt.checked`)."""
        for key in ('frequency_hz', 'stance_fraction', 'step_length_m', 'step_height_m',
                    'start_time_s', 'ramp_time_s', *others):
            if not math.isfinite(getattr(self, key)):
                raise ValueError(f'{key} must be finite, got {getattr(self, key)}')
            object.__setattr__(self, key, float(getattr(self, key)))
        if self.frequency_hz <= 0.0:
            raise ValueError(f'frequency_hz must be > 0, got {self.frequency_hz}')
        if not 0.0 < self.stance_fraction < 1.0:
            raise ValueError(f'stance_fraction must be in (0, 1), got {self.stance_fraction}')
        if self.step_height_m < 0.0 or self.ramp_time_s < 0.0:
            raise ValueError('step_height_m and ramp_time_s must be >= 0')

    def phases(self, t):
        """(N,) phase of each leg in [0, 1) at time t (s); stance while < stance_fraction."""
        return np.mod(self.frequency_hz * (t - self.start_time_s) + self._offsets, 1.0)

    def amplitude(self, t):
        """Stroke and lift scale at time t (s): 0 before start_time_s, 1 after the ramp."""
        if self.ramp_time_s == 0.0:
            return 1.0 if t >= self.start_time_s else 0.0
        return smoothstep((t - self.start_time_s) / self.ramp_time_s)


@dataclass(frozen=True, eq=False)
class StandGait:
    """Hold the neutral stance (`LateralLegs.neutral_angles`) at all times."""
    legs: LateralLegs = hexapod.LEGS

    @property
    def joint_names(self):
        """Joint order of `targets`: '<leg>_knee', '<leg>_ankle' for each leg in legs.names."""
        return _joint_names(self.legs)

    def targets(self, t):
        """Joint position targets (rad), shape (2N,), in `joint_names` order, at time t (s)."""
        return np.stack(self.legs.neutral_angles(), axis=-1).ravel()

    def target_dict(self, t):
        """Joint position targets (rad) at time t (s) as {joint name: value}."""
        return dict(zip(self.joint_names, self.targets(t).tolist()))


@dataclass(frozen=True, eq=False)
class TripodGait(GaitClock, StandGait):
    """Alternating tripod gait (RFT-SiM defaults), walking sideways towards +y of base_link
    (the published gait's heading of 90 deg: the legs move only in the lateral plane).

    Each leg has a phase phi = frac(frequency_hz * (t - start_time_s) + phase_offsets[leg]).
    Stance, phi in [0, stance_fraction): the foot moves at constant speed on the neutral
    height from +step_length_m/2 to -step_length_m/2 along y about its neutral position (so
    the body moves towards +y; a negative step length walks towards -y).
    Swing, the rest of the cycle: the foot returns along a cubic Hermite curve in x that
    matches the stance velocity at both ends (overshooting the stroke by ~4 % of the step
    at stance_fraction 0.5)
    while it rises by step_height_m * sin^2(pi s), s the swing fraction; position and velocity
    are continuous everywhere, so position servos are not kicked.
    Before start_time_s the neutral stance is held; over the next ramp_time_s the stroke and
    the lift grow from 0 to full size with a smoothstep, so the targets stay continuous and
    smooth from the neutral stance. Foot targets become joint targets via `LateralLegs.inverse`.

    frequency_hz: cycles per second. stance_fraction: in (0, 1). step_length_m, step_height_m:
    stroke and lift of the foot tip (m). phase_offsets: leg name -> phase in cycles.
    Raises ValueError if a parameter is out of range or the path leaves the legs' workspace.
    """
    frequency_hz: float = 1.0
    stance_fraction: float = 0.5
    step_length_m: float = 0.05
    step_height_m: float = 0.06
    phase_offsets: Mapping[str, float] = field(
        default_factory=lambda: dict(hexapod.TRIPOD_PHASES))
    start_time_s: float = 0.0
    ramp_time_s: float = 0.5

    def __post_init__(self):
        self.check_values()
        if set(self.phase_offsets) != set(self.legs.names):
            raise ValueError(f'phase_offsets must name exactly the legs {self.legs.names}, '
                             f'got {sorted(self.phase_offsets)}')
        object.__setattr__(self, '_offsets', np.array(
            [float(self.phase_offsets[leg]) for leg in self.legs.names]))
        object.__setattr__(self, '_neutral', self.legs.neutral_feet())
        legs = self.legs  # the arguments of the targets' kernel after the amplitude, once
        object.__setattr__(self, '_tripod', prebuilt.kernel(TRIPOD_TARGETS))
        object.__setattr__(self, '_path_and_legs', (
            self.stance_fraction, self.step_length_m, self.step_height_m, self._neutral,
            legs.knee_xyz, legs.side.astype(float), legs.mid_length, legs.dactyl_length,
            legs.dactyl_droop))
        self._check_workspace()

    def foot_offsets(self, t):
        """Foot targets relative to the neutral feet at time t (s): (dy, dz), each (N,) m,
        dy sideways (+y, the walking direction), dz up, base_link axes."""
        return self._path(self.phases(t), self.amplitude(t))

    def foot_targets(self, t):
        """(N, 2) m: intended sideways position y and height z of each foot tip in base_link
        (its x is its knee axis's)."""
        dy, dz = self.foot_offsets(t)
        return np.stack([self._neutral[:, 1] + dy, self._neutral[:, 2] + dz], axis=-1)

    def targets(self, t):
        """Joint position targets (rad), shape (2N,), in `joint_names` order, at time t (s)."""
        return self._tripod(self.frequency_hz * (t - self.start_time_s), self._offsets,
                            self.amplitude(t), *self._path_and_legs)

    def _path(self, phi, scale):
        """Foot offsets (dy, dz) in m at phases phi (any shape), stroke and lift times scale."""
        phi = np.asarray(phi, dtype=float)
        ds, dz = prebuilt.kernel(FOOT_PATH)(phi.ravel(), self.stance_fraction,
                                            scale * self.step_length_m,
                                            scale * self.step_height_m)
        return ds.reshape(phi.shape), dz.reshape(phi.shape)

    def _check_workspace(self):
        """Raise ValueError unless every foot target over a full cycle is reachable."""
        phi = np.broadcast_to(np.linspace(0.0, 1.0, 721)[:, None], (721, len(self.legs.names)))
        ds, dz = self._path(phi, 1.0)
        bad = ~self.legs.reachable(self._neutral[:, 1] + ds, self._neutral[:, 2] + dz).all(axis=0)
        if bad.any():
            legs = [name for name, b in zip(self.legs.names, bad) if b]
            raise ValueError(
                f'step_length_m={self.step_length_m}, step_height_m={self.step_height_m} '
                f'move the feet of {legs} out of reach or past a joint limit')


GAITS = {'none': StandGait, 'tripod': TripodGait}


def make_gait(name, legs=hexapod.LEGS, **params):
    """Gait `name` ('none' or 'tripod') for `legs`, with keyword parameters of its class."""
    try:
        cls = GAITS[name]
    except KeyError:
        raise ValueError(f'unknown gait {name!r}; choose one of {sorted(GAITS)}') from None
    return cls(legs=legs, **params)
