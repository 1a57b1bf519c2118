"""The bundled quadruped (models/quadruped/quadruped.urdf.xacro): its leg geometry, leg
inverse kinematics and a trot gait.

ROS-free; SI units; base frame +x forward, +z up. Each leg has a hip abduction
(held at 0 by the trot), a hip pitch q1 and a knee q2 about +y; with the thigh (length l1)
and calf (l2) hanging from the hip-pitch axis, the foot centre sits at
    x = -l1 sin q1 - l2 sin(q1 + q2),   z = -l1 cos q1 - l2 cos(q1 + q2)
relative to that axis (q1 > 0 swings the thigh back, q2 < 0 folds the calf forward).

`TrotGait` moves the diagonal pairs (fl, rr) and (fr, rl) half a cycle apart along the foot
path of `gait_kernels.foot_path` (constant-speed stance stroke, smooth swing with
lift), starting from the standing pose with a smoothstep ramp of stroke and lift, so targets
are continuous from the pose the robot holds at start.
"""
from dataclasses import dataclass

import numpy as np

from .. import prebuilt
from ..kernel_names import FOOT_PATH, TROT_TARGETS
from .gaits import GaitClock

#: Legs in the order of the model's ros2_control block and joint tree.
LEGS = ('fl', 'fr', 'rl', 'rr')
#: Joint names in command order: per leg hip_abduction, hip_pitch, knee.
JOINT_NAMES = tuple(f'{leg}_{joint}' for leg in LEGS
                    for joint in ('hip_abduction', 'hip_pitch', 'knee'))
#: Thigh and calf lengths (m): hip-pitch axis to knee axis, knee axis to foot centre.
THIGH_LENGTH = 0.16
CALF_LENGTH = 0.16
#: Standing pose (rad), the xacro's defaults (and its ros2_control initial values).
STAND_HIP = 0.6
STAND_KNEE = -1.2
#: Knee range of the model (rad).
KNEE_RANGE = (-2.6, -0.3)
#: Trot phases (cycles): diagonal pairs half a cycle apart.
TROT_PHASES = {'fl': 0.0, 'rr': 0.0, 'fr': 0.5, 'rl': 0.5}


def leg_forward(hip, knee, l1=THIGH_LENGTH, l2=CALF_LENGTH):
    """Foot centre (x, z), m, relative to the hip-pitch axis for hip pitch and knee (rad)."""
    return (-l1 * np.sin(hip) - l2 * np.sin(hip + knee),
            -l1 * np.cos(hip) - l2 * np.cos(hip + knee))


def leg_inverse(x, z, l1=THIGH_LENGTH, l2=CALF_LENGTH):
    """Hip pitch and knee (rad, knee <= 0) that put the foot centre at (x, z) m relative to
    the hip-pitch axis; arrays broadcast. Raises ValueError if a target is out of reach."""
    x, z = np.asarray(x, dtype=float), np.asarray(z, dtype=float)
    cos_knee = (x * x + z * z - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    if np.any(np.abs(cos_knee) > 1.0):
        raise ValueError('foot target out of the leg\'s reach')
    knee = -np.arccos(cos_knee)
    hip = np.arctan2(-x, -z) + np.arctan2(l2 * np.sin(-knee), l1 + l2 * np.cos(knee))
    return hip, knee


@dataclass(frozen=True, eq=False)
class TrotGait(GaitClock):
    """Trot of the bundled quadruped, walking towards +x of the base.

    Leg phase phi = frac(frequency_hz (t - start_time_s) + TROT_PHASES[leg]) (`phases`, LEGS
    order; `amplitude` is the ramp's scale, both from gaits.GaitClock); stance while
    phi < stance_fraction: the foot moves back from +step_length_m/2 to -step_length_m/2
    at the standing foot height; swing returns it lifted by step_height_m (gait_kernels.foot_path).
    Before start_time_s the standing pose is held; stroke and lift then grow over
    ramp_time_s. Raises ValueError if a parameter is out of range or a foot target leaves
    the leg's reach or the knee's range.
    """
    frequency_hz: float = 1.5
    stance_fraction: float = 0.6
    step_length_m: float = 0.08
    step_height_m: float = 0.05
    start_time_s: float = 0.0
    ramp_time_s: float = 0.5
    stand_hip: float = STAND_HIP
    stand_knee: float = STAND_KNEE

    joint_names = JOINT_NAMES

    def __post_init__(self):
        self.check_values('stand_hip', 'stand_knee')
        object.__setattr__(self, '_offsets', np.array([TROT_PHASES[leg] for leg in LEGS]))
        object.__setattr__(self, '_neutral', tuple(float(v) for v in leg_forward(
            self.stand_hip, self.stand_knee)))
        phi = np.linspace(0.0, 1.0, 361)
        dx, dz = prebuilt.kernel(FOOT_PATH)(phi, self.stance_fraction, self.step_length_m,
                                            self.step_height_m)
        try:
            _, knee = leg_inverse(self._neutral[0] + dx, self._neutral[1] + dz)
        except ValueError:
            knee = np.array([np.nan])
        if not np.all((knee >= KNEE_RANGE[0]) & (knee <= KNEE_RANGE[1])):
            raise ValueError(f'step_length_m={self.step_length_m}, step_height_m='
                             f'{self.step_height_m} move the feet out of reach or past the '
                             f'knee range {KNEE_RANGE} rad')
        object.__setattr__(self, '_trot', prebuilt.kernel(TROT_TARGETS))
        self.targets(self.start_time_s)  # (its kernel loads or compiles now, not mid-run)

    def targets(self, t):
        """Joint position targets (rad), shape (12,), in JOINT_NAMES order, at time t (s)."""
        return self._trot(self.frequency_hz * (t - self.start_time_s), self._offsets,
                             self.amplitude(t), self.stance_fraction, self.step_length_m,
                             self.step_height_m, self._neutral[0], self._neutral[1],
                             THIGH_LENGTH, CALF_LENGTH)
