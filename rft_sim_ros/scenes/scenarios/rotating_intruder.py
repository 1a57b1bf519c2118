"""rotating_intruder: the rail rig with its carriage fixed; the servo torque that sand adds.

RFT-SiM's first baseline: an intruder on a fixed-base servo turned 180 deg through the sand
at `speed` rad/s (models/rail_intruder.xml with the rail joint removed; geometry, servo and
scene values as in rail_intruder). The torque the sand adds is measured as the paper
measured it: servo torque in sand minus servo torque for the same commanded motion in air.
The motion in air is simulated alongside, in lockstep: a second MjData of the same model,
without sand forces, given the same servo targets every step.

Metrics (SI; torques about the axle, positive against the motion):
  peak_torque_increase_Nm  max over time of (servo torque in sand - servo torque in air);
  peak_sand_torque_Nm      max of the RFT torque about the axle (engine wrenches): the same
                           quantity measured from the sand side, a consistency check;
  peak_servo_torque_Nm, peak_servo_torque_air_Nm  the two servo torques' maxima;
  angle_at_peak_deg        rotation (from the start) at the peak torque increase;
  max_sinkage_m, rotation_deg  as in rail_intruder.
"""
import mujoco
import numpy as np

from . import rail_intruder


class Scenario(rail_intruder.Scenario):
    coast_time = 0.15  # s after the rotation (duration: auto)

    observe_interval = 1  # the air twin steps with every step of the sand run
    columns = rail_intruder.Scenario.columns + ('air_torque_Nm',)

    def edit_model(self, spec):
        super().edit_model(spec)
        spec.delete(spec.joint('rail'))

    def initialize(self, sim):
        super().initialize(sim)
        self._air = mujoco.MjData(sim.model)
        self._air.qpos[:] = sim.data.qpos
        mujoco.mj_forward(sim.model, self._air)

    def observe(self, sim):
        self._air.ctrl[:] = sim.data.ctrl  # the targets the sand run just used
        mujoco.mj_step(sim.model, self._air)
        self._rows.append(self._sample(sim)
                          + (self.direction * self._air.actuator_force[self._actuator],))

    def metrics(self, sim):
        s = self.series()
        if not len(s['time_s']):
            return {}
        increase = s['servo_torque_Nm'] - s['air_torque_Nm']
        peak = int(np.argmax(increase))
        swept = self.direction * (s['angle_rad'] - self.start_angle)
        return {
            'peak_torque_increase_Nm': float(increase[peak]),
            'peak_sand_torque_Nm': float(s['sand_torque_Nm'].max()),
            'peak_servo_torque_Nm': float(s['servo_torque_Nm'].max()),
            'peak_servo_torque_air_Nm': float(s['air_torque_Nm'].max()),
            'angle_at_peak_deg': float(np.degrees(swept[peak])),
            'max_sinkage_m': float(s['tip_sinkage_m'].max()),
            'rotation_deg': float(np.degrees(swept[-1])),
        }
