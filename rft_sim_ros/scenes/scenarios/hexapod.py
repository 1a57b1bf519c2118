"""hexapod: the RFT-SiM 12-DOF crab hexapod dropped onto sand, then walking a built-in gait.

Model: models/hexapod.xml (4.04 kg, docs/hexapod.md) plus `payload` kg added to the box on
its plate through MjSpec. At t = 0 the robot is held in the neutral stance (the model's
keyframe "home") with its foot tips `drop_height` m above the sand and released; after
`settle_time` s the gait starts (`gait`: 'tripod' = the alternating tripod of
rft_sim_ros.scenes.gaits with the scene's frequency / stance / step length / lift, walking
sideways; 'none' = no built-in commands, the servos hold the neutral stance or whatever an
external controller sends through `sim.commands`).

The walk that the metrics describe is the `cycles` gait cycles after `settle_time` (or as
much of it as was run). Frames: world (odom), z up; the robot starts with its long axis
along world x, so it walks (sideways, like a crab) along world +y; SI units.

Metrics ("forward" is the walking direction, world +y):
  forward_distance_m    base_link displacement along world +y over the walk;
  lateral_drift_m       ... along world x (the body's long axis at the start);
  mean_speed_mps        forward_distance_m / walk time;
  mean_sinkage_m        foot-tip depth below the sand surface, averaged over all legs and
                        samples while the leg is in stance (gait phase < stance fraction;
                        'none': all legs, the whole walk window); a tip above the surface
                        counts 0;
  backward_fraction     summed backward (-y) base motion over summed forward motion during
                        the walk (the paper's "backward motion ... of the forward motion"),
                        from the base y sampled every `observe_interval` steps, counting
                        only samples moving faster than MOTION_NOISE_MPS (so a robot that
                        stands still, jittering by nanometres, has 0, not a ratio of noise);
  settled_base_height_m base_link height at the start of the walk;
  walk_peak_force_z_N_<leg>
                        largest vertical sand force on the leg during the walk (from
                        settle_time on; the generic peak_force_z_N_<leg> covers the whole
                        run, the landing included);
  total_mass_kg         mass of the compiled model.
"""
from functools import partial

import numpy as np

from ..gaits import make_gait
from ..hexapod import FOOT_SITES, LEG_NAMES, LEGS, PAYLOAD_BODY
from . import BaseScenario

#: Height of base_link above the foot tips in the neutral stance, m (docs/hexapod.md).
NEUTRAL_FOOT_DROP_M = LEGS.neutral_down - LEGS.knee_xyz[0, 2]

GAIT_NAMES = ('none', 'tripod')

#: Base speeds along y below this (m/s; 1.4 % of the default walk's mean speed) are rest,
#: not forward or backward motion, in backward_fraction.
MOTION_NOISE_MPS = 1e-3


class Scenario(BaseScenario):
    observe_interval = 10  # samples every 8 ms at the 0.8 ms timestep

    def duration(self):
        """Settling plus the gait cycles the metrics cover."""
        return self.settle_time + self.walk_time

    def __init__(self, scene):
        super().__init__(scene)
        self.payload = self.number('payload', minimum=0.0)
        self.drop_height = self.number('drop_height', minimum=0.0)
        self.settle_time = self.number('settle_time', minimum=0.0)
        self.cycles = self.number('cycles', positive=True)
        self.frequency = self.number('frequency', positive=True)
        self.stance_fraction = self.number('stance_fraction', minimum=0.0, maximum=1.0)
        self.gait = None
        if self.choice('gait', GAIT_NAMES) == 'tripod':
            self.gait = self.walking_gait(partial(make_gait, 'tripod'))
        self.walk_time = self.cycles / self.frequency
        self._samples = []

    def edit_model(self, spec):
        spec.body(PAYLOAD_BODY).mass += self.payload

    def initialize(self, sim):
        qpos = sim.data.joint('base_free').qpos
        qpos[:3] = (0.0, 0.0,
                    self._ground(sim) + self.drop_height + NEUTRAL_FOOT_DROP_M)
        qpos[3:] = (1.0, 0.0, 0.0, 0.0)
        self._base = sim.model.body(sim.base_body).id
        self._feet = np.array([sim.model.site(name).id for name in FOOT_SITES])
        names = sim.engine.body_names
        self._leg_sum = np.zeros((len(LEG_NAMES), len(names)))  # sand body -> its leg
        for row, leg in enumerate(LEG_NAMES):
            for body in sim.legs[leg]:
                self._leg_sum[row, names.index(body)] = 1.0
        self._samples = []

    @staticmethod
    def _ground(sim, reach=0.3):
        """Highest sand surface within `reach` m of the origin (where the robot starts), m."""
        x, y = np.meshgrid(np.linspace(-reach, reach, 31), np.linspace(-reach, reach, 31))
        return float(np.max(sim.engine.surface.height(x, y)))

    def control(self, sim):
        # the gait's clock is the time since this run (or reset) started: sim.data.time
        if self.gait is not None:
            # (the gait's own new array of finite targets: held without the checks)
            sim.commands.hold_positions(self.gait.targets(sim.data.time), now=sim.time)

    def observe(self, sim):
        t = sim.data.time
        if not self.settle_time <= t <= self.settle_time + self.walk_time + 1e-9:
            return
        d = sim.data
        tips = d.site_xpos[self._feet]
        sample = np.empty(16)  # t, base x y z, tips above the sand (6), legs' force z (6)
        sample[0] = t
        sample[1:4] = d.xpos[self._base]
        sample[4:10] = tips[:, 2] - sim.engine.surface.height(tips[:, 0], tips[:, 1])
        sample[10:] = self._leg_sum @ sim.engine.body_wrenches[:, 2]
        self._samples.append(sample)

    def series(self):
        """The walk's time course: {'time_s', 'x_m', 'y_m', 'z_m'} (base_link origin, world)
        and 'sinkage_m' (mean stance foot-tip depth), (n,) arrays."""
        s = np.array(self._samples) if self._samples else np.zeros((0, 16))
        depth = np.maximum(-s[:, 4:10], 0.0)  # below the local surface
        stance = self._stance(s[:, 0])
        counts = stance.sum(axis=1)
        sinkage = np.where(counts > 0, (depth * stance).sum(axis=1) / np.maximum(counts, 1), 0.0)
        return {'time_s': s[:, 0], 'x_m': s[:, 1], 'y_m': s[:, 2], 'z_m': s[:, 3],
                'sinkage_m': sinkage}

    def _stance(self, times):
        """(n, 6) bool: which legs are in stance at the given gait times (s)."""
        if self.gait is None:
            return np.ones((len(times), len(LEG_NAMES)), dtype=bool)
        return self.gait.phases(np.asarray(times)[:, None]) < self.stance_fraction

    def metrics(self, sim):
        total_mass = float(np.sum(sim.model.body_mass))
        if len(self._samples) < 2:
            return {'total_mass_kg': total_mass, 'walk_time_s': 0.0}
        s = np.array(self._samples)
        times, base, tips_above, legs_fz = s[:, 0], s[:, 1:4], s[:, 4:10], s[:, 10:16]
        walked = times[-1] - times[0]
        forward = base[-1, 1] - base[0, 1]
        steps = np.diff(base[:, 1])
        steps = steps[np.abs(steps) > MOTION_NOISE_MPS * np.diff(times)]
        ahead = steps[steps > 0].sum()
        depth = np.maximum(-tips_above, 0.0)
        stance = self._stance(times)
        metrics = {
            'forward_distance_m': float(forward),
            'lateral_drift_m': float(base[-1, 0] - base[0, 0]),
            'mean_speed_mps': float(forward / walked) if walked > 0 else 0.0,
            'mean_sinkage_m': float(depth[stance].mean()) if stance.any() else 0.0,
            'backward_fraction': float(-steps[steps < 0].sum() / ahead) if ahead > 0 else 0.0,
            'settled_base_height_m': float(base[0, 2]),
            'walk_time_s': float(walked),
            'total_mass_kg': total_mass,
        }
        for i, leg in enumerate(LEG_NAMES):
            metrics[f'walk_peak_force_z_N_{leg}'] = float(legs_fz[:, i].max())
        return metrics
