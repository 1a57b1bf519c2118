"""A scenario for the bipedal test robot (biped.xml, keyframe `stand`): it walks, each foot
in turn lifted out of the sand, swung forward by `stride` (rad of hip pitch) and set down
again while the other pushes back, the weight shifted over the standing foot by the hip
rolls, at `params.frequency` (Hz, default 1) after `params.settle_time`
(s, default 0.5): a humanoid walking for the step-cost bench (rft_sim_ros.bench.other_bodies),
its feet entering and leaving the sand, its shins and thighs just above it.

Each leg's pitch joints keep its foot level (hip + knee + ankle = 0): in its swing half-cycle
the knee bends by `2 lift` (rad) and hip and ankle by `lift` each, a half sine, which raises
the foot ~3 cm at lift 0.15; the hip rolls lean the trunk over the stance foot by `sway`
(rad). No balance control: it walks slowly where its soles hold it."""
import math

import numpy as np

from rft_sim_ros.scenes.scenarios import BaseScenario

STAND = {'hip_roll': 0.0, 'hip_pitch': -0.3, 'knee': 0.6, 'ankle_pitch': -0.3, 'ankle_roll': 0.0}


class Scenario(BaseScenario):
    def __init__(self, scene):
        super().__init__(scene)
        self.frequency = self.number('frequency', positive=True) if 'frequency' in \
            scene.params else 1.0
        self.settle_time = float(scene.params.get('settle_time', 0.5))
        self.lift = float(scene.params.get('lift', 0.15))
        self.sway = float(scene.params.get('sway', 0.06))
        self.stride = float(scene.params.get('stride', 0.06))
        self._index = None

    def control(self, sim):
        names = list(sim.servo_joint_names)
        if self._index is None:
            self._index = {name: names.index(name) for name in names}
        t = sim.data.time - self.settle_time
        phase = 2 * math.pi * self.frequency * max(t, 0.0)
        ramp = min(max(t, 0.0) / 0.5, 1.0)
        targets = np.zeros(len(names))
        for side, sign in (('left', 1.0), ('right', -1.0)):
            swing = ramp * max(0.0, sign * math.sin(phase))  # left swings first
            for joint, value in STAND.items():
                name = f'{side}_{joint}'
                if name in self._index:
                    targets[self._index[name]] = value
            bend = self.lift * swing
            targets[self._index[f'{side}_hip_pitch']] -= bend
            targets[self._index[f'{side}_knee']] += 2 * bend
            targets[self._index[f'{side}_ankle_pitch']] -= bend
            # the swinging leg swings forward, the standing one pushes back
            stroke = sign * self.stride * ramp * math.cos(phase)
            targets[self._index[f'{side}_hip_pitch']] += stroke
            targets[self._index[f'{side}_ankle_pitch']] -= stroke
            # lean over the stance foot (+ roll: towards -y, the right foot, while left swings)
            roll = self.sway * ramp * math.sin(phase)
            targets[self._index[f'{side}_hip_roll']] = roll
            targets[self._index[f'{side}_ankle_roll']] = -roll
        sim.commands.set_positions(targets, now=sim.time)
