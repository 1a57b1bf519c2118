"""Hybrid joint commands: position, velocity, feed-forward effort and gains per joint.

The law (what a Unitree-style motor driver or a learned policy's PD stage computes), per joint:

    tau = kp (q* - q) + kd (dq* - dq) + tau_ff,   clipped to [-effort limit, +effort limit]

q*: commanded position (rad or m), dq*: commanded velocity (rad/s or m/s), tau_ff: feed-forward
effort (N m or N); q, dq: the joint's position and velocity; kp in N m/rad (N/m), kd in
N m s/rad (N s/m); the effort limit is the joint's (`servos` effort, else the model's or the
description's; none: unclipped). The simulation applies it through the joint's position
actuator with MuJoCo's implicit damping (`rft_sim_ros.sim.hybrid_drive`), so any kd that
the position servo tolerates is stable at the scene's timestep.

ROS-free. `HybridTargets` holds q*, dq*, tau_ff of every commanded joint and takes
`JointStateCommand`s (`joint_state_commands`): a finite value sets that interface, NaN leaves
it. It starts from the joints' targets at the moment hybrid commands begin, velocity and
feed-forward 0, so a position-only command stream is the position servo with these gains.
A joint whose <ros2_control> block declares a velocity command interface and no position
one (a wheel under a velocity controller) has its q* move at its dq* (`advance`), so that
it turns at that speed as a velocity servo with integral action does, rather than kp
holding it where hybrid commands began; one that declares neither (an effort interface
alone) is not `tracked`: its kp and kd terms are off, tau = tau_ff. (The declarations come
with each command: `JointStateCommand.position_declared`, `velocity_declared`.)

Gains come from glob patterns over joint names, later patterns overriding earlier ones (as
the scene's `servos`): {pattern: {kp: ..., kd: ...}}; joints no pattern names keep their
position servo's gains. `gain_patterns` reads them from a mapping (a scene's `joint_gains`)
or from 'PATTERN: {kp: X, kd: Y}' strings (the node's `joint_gains` parameter).
"""
import fnmatch
import math

import numpy as np
import yaml


def _gain_value(pattern, key, value):
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value) or value < 0:
        raise ValueError(f'{pattern}.{key}: must be a finite number >= 0, got {value!r}')
    return float(value)


def _gain_entry(text):
    """(pattern, settings) of a 'PATTERN: {kp: X, kd: Y}' string (the pattern unquoted, as
    globs like '*_knee' are no YAML)."""
    pattern, _, settings = text.partition(':')
    try:
        settings = yaml.safe_load(settings) if pattern.strip() else None
    except yaml.YAMLError:
        settings = None
    if not isinstance(settings, dict):
        raise ValueError(f"joint gains entry {text!r}: write 'PATTERN: {{kp: X, kd: Y}}'")
    return pattern.strip(), settings


def gain_patterns(entries):
    """{pattern: {'kp'?: float, 'kd'?: float}} from a mapping of the same shape or a list of
    'PATTERN: {kp: X, kd: Y}' strings (YAML; an empty one names nothing, so that `['']`, which
    the ros2 command line can type where it cannot type an empty string list, gives the
    defaults back); raises ValueError naming the bad entry."""
    if isinstance(entries, dict):
        items = list(entries.items())
    elif isinstance(entries, (list, tuple)):
        items = [_gain_entry(str(text)) for text in entries if str(text).strip()]
    else:
        raise ValueError(f'joint gains must map joint patterns to {{kp, kd}}, got {entries!r}')
    patterns = {}
    for pattern, settings in items:
        if not isinstance(settings, dict) or not settings or not set(settings) <= {'kp', 'kd'}:
            raise ValueError(f'{pattern}: give kp and/or kd, got {settings!r}')
        patterns[str(pattern)] = {key: _gain_value(pattern, key, value)
                                  for key, value in settings.items()}
    return patterns


def resolve_gains(patterns, joint_names, default_kp, default_kd):
    """(kp, kd) float arrays in `joint_names` order: each joint's defaults (its position
    servo's gains) overridden by every pattern of `patterns` (`gain_patterns`) it matches, in
    order."""
    kp = np.array(default_kp, dtype=float)
    kd = np.array(default_kd, dtype=float)
    for pattern, settings in patterns.items():
        for i, name in enumerate(joint_names):
            if fnmatch.fnmatchcase(name, pattern):
                kp[i] = settings.get('kp', kp[i])
                kd[i] = settings.get('kd', kd[i])
    return kp, kd


class HybridTargets:
    """q* (rad or m), dq* (rad/s or m/s), tau_ff (N m or N) of every commanded joint, in the
    command handler's joint order; starts at `positions`, velocity and effort 0."""

    def __init__(self, positions, now=0.0):
        self.positions = np.array(positions, dtype=float)
        self.velocities = np.zeros_like(self.positions)
        self.efforts = np.zeros_like(self.positions)
        self.moving = np.zeros(self.positions.shape, dtype=bool)  # q* moves at dq*
        self.tracked = np.ones(self.positions.shape, dtype=bool)  # kp and kd act
        self._time = float(now)  # sim time s q* was last advanced to

    def update(self, command, now=None):
        """Apply a `JointStateCommand` at sim time `now` (s; None: the time last advanced
        to): its finite values set their interfaces."""
        if now is not None:
            self.advance(now)
        for target, values in ((self.positions, command.positions),
                               (self.velocities, command.velocities),
                               (self.efforts, command.efforts)):
            given = ~np.isnan(values)
            target[command.joints[given]] = values[given]
        if command.position_declared is not None:
            joints, position = command.joints, command.position_declared
            self.moving[joints] = ~position
            self.tracked[joints] = position | command.velocity_declared

    def advance(self, now):
        """Move the position target of every joint that declares a velocity command
        interface and no position one at its velocity target, to sim time `now` (s);
        returns self."""
        moving = self.moving & self.tracked
        if moving.any():
            self.positions[moving] += self.velocities[moving] * (now - self._time)
        self._time = float(now)
        return self

