"""Apply hybrid joint commands (`rft_sim_ros.control.hybrid`) through the position actuators.

A joint's position actuator (MuJoCo: force = gain * ctrl + b0 + b1 q + b2 dq, clamped to its
force range) is re-parameterised while hybrid mode is on: gain 1, bias (0, -kp, -kd), force
range +-effort limit, no control range, and

    ctrl = kp q* + kd dq* + tau_ff

so its force is exactly kp (q* - q) + kd (dq* - dq) + tau_ff clipped to the effort limit
(q* held within the joint's range where it has one, as the position servos' targets are;
kp and kd 0 for a joint that declares an effort command interface alone:
`HybridTargets.tracked`),
with the -kd dq term integrated implicitly by MuJoCo (implicitfast) and by the sand engine's
implicit solve, as the position servos' damping is. Leaving hybrid mode restores every
parameter it changed. The effort motors stay at 0 meanwhile.
"""
import numpy as np

from rft_sim_ros.control.hybrid import resolve_gains


class HybridDrive:
    """Hybrid mode of a model's `robot.joints.JointInterfaces` (`interfaces`).

    gains: {pattern: {kp, kd}} (`control.hybrid.gain_patterns`, a scene's joint_gains); joints
    not named keep their position servo's gains (`interfaces.gains`).
    """

    def __init__(self, model, interfaces, gains=None):
        self._model = model
        self._interfaces = interfaces
        self._actuators = interfaces.position_actuators
        names = interfaces.joint_names
        self._default = resolve_gains(gains or {}, names, [interfaces.gains[n].kp for n in names],
                                      [interfaces.gains[n].kd for n in names])
        self._low, self._high = interfaces.ranges.T  # q* within these (rad or m)
        limits = np.array([interfaces.gains[n].effort for n in names], dtype=float)
        self._limited = np.isfinite(limits)
        self._limits = limits
        self._saved = None
        self._tracked = np.ones(len(names), dtype=bool)  # joints whose kp, kd act
        self.set_gains({})

    @property
    def engaged(self):
        """Whether the position actuators are set up for hybrid commands."""
        return self._saved is not None

    def set_gains(self, patterns):
        """Use the gains of `patterns` (`gain_patterns`) over those given at construction
        ({}: those alone) from the next control tick on."""
        self.kp, self.kd = resolve_gains(patterns, self._interfaces.joint_names, *self._default)
        if self.engaged:
            self._set_bias()

    def _set_bias(self):
        m, a = self._model, self._actuators
        m.actuator_biasprm[a, 0] = 0.0
        m.actuator_biasprm[a, 1] = -self.kp * self._tracked
        m.actuator_biasprm[a, 2] = -self.kd * self._tracked

    def engage(self):
        """Position actuators in hybrid form (module docstring); the effort motors off."""
        if self.engaged:
            return
        m, a = self._model, self._actuators
        self._interfaces.set_mode('position')  # (the position actuators' own parameters)
        self._saved = (m.actuator_gainprm[a].copy(), m.actuator_biasprm[a].copy(),
                       m.actuator_ctrllimited[a].copy(), m.actuator_forcelimited[a].copy(),
                       m.actuator_forcerange[a].copy())
        m.actuator_gainprm[a] = 0.0
        m.actuator_gainprm[a, 0] = 1.0
        self._set_bias()
        m.actuator_ctrllimited[a] = 0
        limited = a[self._limited]
        m.actuator_forcelimited[limited] = 1
        m.actuator_forcerange[limited, 0] = -self._limits[self._limited]
        m.actuator_forcerange[limited, 1] = self._limits[self._limited]
        self._interfaces.mode = 'hybrid'

    def release(self):
        """Position actuators back as they were (the interfaces' position mode)."""
        if not self.engaged:
            return
        m, a = self._model, self._actuators
        (m.actuator_gainprm[a], m.actuator_biasprm[a], m.actuator_ctrllimited[a],
         m.actuator_forcelimited[a], m.actuator_forcerange[a]) = self._saved
        self._saved = None
        self._interfaces.mode = 'position'

    def controls(self, targets, positions_now):
        """ctrl values of the position actuators for `targets` (control.hybrid.HybridTargets)
        with the joints at `positions_now` (rad or m, the same order). q* is kept within the
        joint's range and, where it moves at dq* (`HybridTargets.moving`), within the lag
        whose kp term alone reaches the effort limit: a stalled joint (a wheel held in the
        sand) pushes at its limit without winding q* up, so it does not race to catch up
        once free, as a velocity servo's integrator with anti-windup does not."""
        if not np.array_equal(targets.tracked, self._tracked):
            self._tracked = targets.tracked.copy()
            self._set_bias()
        lag = np.where(targets.moving & self._limited & (self.kp > 0.0),
                       self._limits / np.maximum(self.kp, 1e-300), np.inf)
        low = np.maximum(self._low, positions_now - lag)
        high = np.minimum(self._high, positions_now + lag)
        positions = np.clip(targets.positions, low, high,
                            out=targets.positions)  # (kept so: no windup)
        return self._tracked * (self.kp * positions + self.kd * targets.velocities) \
            + targets.efforts

