"""Joints pushed through their limits, said rather than left to look like a robot's pose.

MuJoCo's joint limits are soft constraints (their solref: a spring and damper that lets the
joint into the stop by what pushes it), so a push far beyond what that spring holds drives
a joint well past the range the model gives it: an effort command, a model's own position
actuator without a control range, a heavy load. (The position servos this package adds
hold their targets within the joint's range: robot/joints.py.) A real stop allows none of
that.

`LimitWatch` looks, at the outcome's looks (sim/outcome.py), at every limited hinge and
slide joint of the model and records the one that went farthest past its range, counted in
OVERRUN_RAD (hinges) or OVERRUN_M (slides): what a soft limit yields under a load it holds
stays well within them.
"""
import math

import mujoco
import numpy as np

#: rad: a hinge this far past its range has been pushed through its stop.
OVERRUN_RAD = math.radians(5.0)
#: m: a slide this far past its range has been pushed through its stop.
OVERRUN_M = 0.005

_HINGE, _SLIDE = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)


class LimitWatch:
    """The limited hinge and slide joints of `model`, and how far past its range the one
    farthest past went (`observe`, `result`)."""

    def __init__(self, model):
        joints = [j for j in range(model.njnt) if model.jnt_limited[j]
                  and int(model.jnt_type[j]) in (_HINGE, _SLIDE)]
        self._names = [model.joint(j).name or f'joint #{j}' for j in joints]
        self._hinge = np.array([int(model.jnt_type[j]) == _HINGE for j in joints], dtype=bool)
        self._address = np.array(model.jnt_qposadr[joints], dtype=int)
        self._low, self._high = np.array(model.jnt_range[joints], dtype=float).reshape(-1, 2).T
        self._scale = np.where(self._hinge, OVERRUN_RAD, OVERRUN_M)
        self.start()

    def start(self):
        """From a (re)start: nothing seen yet."""
        self._worst = None  # (past / scale, index, past rad or m, the limit past, time s)

    def observe(self, data, time):
        """One look at `data` at sim time `time` (s)."""
        if not self._address.size:
            return
        q = data.qpos[self._address]
        past = np.maximum(self._low - q, q - self._high)
        score = past / self._scale
        score[~np.isfinite(score)] = -np.inf  # (a diverged joint hides no other)
        i = int(np.argmax(score))
        if score[i] > 1.0 and (
                self._worst is None or score[i] > self._worst[0]):
            limit = self._high[i] if q[i] > self._high[i] else self._low[i]
            self._worst = (float(score[i]), i, float(past[i]), float(limit), time)

    def result(self):
        """{joint, past_limit_rad or past_limit_m, limit_rad or limit_m (the end of its range
        it went past), time_s} of the joint farthest past its range by more than OVERRUN_RAD
        or OVERRUN_M, at the look that saw it farthest; None: none went so far."""
        if self._worst is None:
            return None
        _, i, past, limit, time = self._worst
        unit = 'rad' if self._hinge[i] else 'm'
        return {'joint': self._names[i], f'past_limit_{unit}': past, f'limit_{unit}': limit,
                'time_s': time}


def words(past):
    """A `LimitWatch.result` in words."""
    if 'past_limit_rad' in past:
        amount = f"{math.degrees(past['past_limit_rad']):.0f} deg"
        limit = f"{past['limit_rad']:.3g} rad"
    else:
        amount, limit = f"{past['past_limit_m'] * 100:.3g} cm", f"{past['limit_m']:.3g} m"
    return (f"joint {past['joint']} went {amount} past its limit ({limit}) at t = "
            f"{past['time_s']:.2f} s: MuJoCo's joint limits are soft, and what pushed it (its "
            "actuator, an effort command, the load) went through (an effort limit, servos: "
            '{JOINT: {effort: ...}}, caps a servo)')
