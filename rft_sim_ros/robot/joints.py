"""Joint command interfaces as a ros2_control robot has them: position and effort per joint.

Every actuated joint (hinge or slide) gets a position command interface and an effort one,
set up on the model spec before it is compiled (`add_joint_interfaces`) and tuned on the
compiled model (`JointInterfaces`). Actuated: a joint the model drives with an actuator of
its own; in a model that declares no actuator at all (a URDF, whose joints ros2_control
drives; an MJCF without <actuator>), every movable joint. A joint without an actuator in a
model that has actuators stays passive as written (its spring, damping, friction and limits
are the model's; a closed loop's or a spring leg's free joints stay free) unless the scene's
`servos` names it (a matching pattern with kp, kd or effort): then it gets interfaces too.

* position: a MuJoCo position actuator already on the joint is used as it is. A joint driven
  by a torque `<motor>`, or by no actuator, gets a PD actuator that MuJoCo integrates itself
  (a `general` actuator with gain kp and bias -kp q - kd qdot, its force clamped to the
  effort limit), so the damping is implicit in MuJoCo's implicitfast step and in the sand
  engine's implicit solve, and stays stable at the scene timestep; on a joint with limits its
  target is held within the joint's range (its control range: a command beyond it holds
  the joint at its stop, as ros2_control's joint limiters and MuJoCo's own position
  actuators with a ctrlrange do, instead of driving it into MuJoCo's soft limit). Gains per
  joint come from the scene's `servos` (glob pattern -> {kp, kd, effort}; later patterns
  win) or, by default, from the robot's mass (`default_gains`).
* effort: a `<motor>` already on the joint, else an added motor (N m or N; clamped to the
  effort limit).

Effort limit of a joint: `servos` effort, else its motor's ctrlrange x gear (or forcerange),
else the description's limit (URDF `<limit effort>`), else none.

One mode at a time, as ros2_control switches controllers: a position command puts every
joint in position mode (PD/position actuators on, motors at 0), an effort command puts them
in effort mode (position actuators' gains off). A joint whose `servos` entry is `passive`
(the model's own actuators on it, if any, switched off: a fixed gain of 0 and no bias, no
force; actuators on tendons or sites across it are kept), that has no actuator where the
model has some (above), that is driven by another actuator kind (velocity, integrated
velocity, a muscle...; `other_driven`: its control stays 0, a velocity actuator holds it
still) unless `servos` names it (then those actuators are switched off, as for passive, and
it gets a PD and a motor as a joint without an actuator does: `replaced`), that has no
name (no command could name it; /joint_states leaves it out too), or that an active joint
equality sets from another joint or a constant (a URDF `<mimic>` joint, which MuJoCo's
importer makes one; MJCF `<equality><joint joint1=...>`) gets no interfaces: it follows,
as a ros2_control mimic joint does, instead of a servo fighting the equality. Other
equality constraints (an MJCF's closed loops: `connect`, `weld`) are kept as written.
"""
import fnmatch
import math
from dataclasses import dataclass

import mujoco
import numpy as np

#: Default stiffness rule: the robot's whole weight on a joint's reach deflects a hinge by
#: SAG_RAD, a slide by SAG_M.
SAG_RAD = 0.05
SAG_M = 0.005
GRAVITY = 9.81

PASSIVE = 'passive'
_PD_PREFIX = 'pd_'
_EFFORT_PREFIX = 'effort_'
_MOVABLE = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)


def movable_joints(model):
    """Ids of the hinge and slide joints of compiled `model` (the joints with a position)."""
    return [j for j in range(model.njnt) if mujoco.mjtJoint(int(model.jnt_type[j])) in _MOVABLE]


def servo_settings(servos, joint):
    """The `servos` settings ({kp, kd, effort} or PASSIVE) of joint name `joint`: the
    entries of every matching glob pattern, in order, later ones overriding."""
    merged = {}
    for pattern, settings in servos.items():
        if fnmatch.fnmatchcase(joint, pattern):
            if settings == PASSIVE:
                merged = PASSIVE
            else:
                merged = {**(merged if isinstance(merged, dict) else {}), **settings}
    return merged


def check_servos(servos):
    """`servos` ({pattern: {kp, kd, effort} or 'passive'}) checked; raises ValueError."""
    if not isinstance(servos, dict):
        raise ValueError(f'must map joint patterns to {{kp, kd, effort}} or passive, got '
                         f'{servos!r}')
    for pattern, settings in servos.items():
        if settings == PASSIVE:
            continue
        if not isinstance(settings, dict) or not set(settings) <= {'kp', 'kd', 'effort'}:
            raise ValueError(f'{pattern}: give kp, kd and/or effort, or passive; got '
                             f'{settings!r}')
        for key, value in settings.items():
            if (isinstance(value, bool) or not isinstance(value, (int, float))
                    or not math.isfinite(value) or value < 0 or (key != 'kd' and value == 0)):
                raise ValueError(f'{pattern}.{key}: must be a finite number > 0 '
                                 f'(kd >= 0), got {value!r}')
    return servos


def _is_position_servo(gaintype, biastype, dyntype, gainprm, biasprm):
    return (gaintype == mujoco.mjtGain.mjGAIN_FIXED and biastype == mujoco.mjtBias.mjBIAS_AFFINE
            and dyntype == mujoco.mjtDyn.mjDYN_NONE and gainprm[0] != 0
            and biasprm[1] == -gainprm[0])


def _is_motor(gaintype, biastype, dyntype):
    return (gaintype == mujoco.mjtGain.mjGAIN_FIXED and biastype == mujoco.mjtBias.mjBIAS_NONE
            and dyntype == mujoco.mjtDyn.mjDYN_NONE)


def position_servos(model):
    """[(actuator id, joint id)] of the MuJoCo position actuators of a compiled model acting
    on a joint: no activation dynamics, a fixed gain kp and an affine bias -kp q (what
    <position> compiles to), in actuator order."""
    return [(a, int(model.actuator_trnid[a, 0])) for a in range(model.nu)
            if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT and _is_position_servo(
                model.actuator_gaintype[a], model.actuator_biastype[a],
                model.actuator_dyntype[a], model.actuator_gainprm[a], model.actuator_biasprm[a])]


@dataclass(frozen=True)
class JointPlan:
    """What `add_joint_interfaces` did: `commanded`, the joints that got interfaces (in
    model order); `passive`, the named movable joints that move freely: those the model
    gives no actuator (no servo asked for them), as the model has them, and those `servos`
    makes passive; `unactuated`, those the model gives no actuator; `switched_off`, the
    names of the model's actuators on joints `servos` makes passive, switched off;
    `other_driven`, the named joints driven by another actuator kind, without interfaces;
    `replaced`, the names of the model's actuators of another kind on joints `servos` gives
    a servo, switched off."""
    commanded: tuple
    passive: tuple
    unactuated: tuple
    switched_off: tuple
    other_driven: tuple = ()
    replaced: tuple = ()


def add_joint_interfaces(spec, servos):
    """Add the PD and effort actuators that the actuated joints of `spec` (mujoco.MjSpec)
    lack (module docstring), and those `servos` asks for on joints without an actuator.
    Returns a JointPlan; the actuators are named pd_<joint> / effort_<joint>. Switches an
    Euler integrator to implicitfast when a PD actuator was added (its damping must be
    implicit)."""
    by_joint = {}
    for actuator in spec.actuators:
        if actuator.trntype == mujoco.mjtTrn.mjTRN_JOINT:
            by_joint.setdefault(actuator.target, []).append(actuator)
    every_joint = not spec.actuators  # no actuator of its own: every joint is commanded
    followers = {e.name1 for e in spec.equalities if e.type == mujoco.mjtEq.mjEQ_JOINT
                 and e.active}
    names = [joint.name for joint in spec.joints if joint.name and joint.type in _MOVABLE]
    unmatched = [pattern for pattern in servos
                 if not any(fnmatch.fnmatchcase(name, pattern) for name in names)]
    if unmatched:
        raise ValueError(f'servos: {", ".join(map(repr, unmatched))} match'
                         f'{"es" * (len(unmatched) == 1)} no joint of the model (its joints: '
                         f'{", ".join(names) or "none"})')
    joints, passive, unactuated, switched_off, added_pd = [], [], [], [], False
    other_driven, replaced = [], []
    for joint in spec.joints:
        settings = servo_settings(servos, joint.name)
        if joint.type not in _MOVABLE or joint.name in followers:
            continue
        actuators = by_joint.get(joint.name, [])
        if settings == PASSIVE:  # free: the model's own actuators on it exert no force
            switched_off += _switch_off(actuators, joint.name)
            if joint.name:
                passive.append(joint.name)
            continue
        if not (actuators or every_joint or settings):
            if joint.name:
                passive.append(joint.name)
                unactuated.append(joint.name)
            continue  # no actuator in the model, and the scene asks for no servo
        position = [a for a in actuators if _is_position_servo(
            a.gaintype, a.biastype, a.dyntype, a.gainprm, a.biasprm)]
        motors = [a for a in actuators if _is_motor(a.gaintype, a.biastype, a.dyntype)]
        if not joint.name:
            continue  # no name to command it by
        if len(position) + len(motors) < len(actuators):  # driven by another actuator kind
            if not settings:
                other_driven.append(joint.name)
                continue
            replaced += _switch_off(actuators, joint.name)  # (servos asks for its servo)
            position = motors = []
        if not position:
            _add_actuator(spec, _PD_PREFIX + joint.name, joint.name).set_to_position(
                kp=1.0, kv=0.0)  # gains set on the compiled model (JointInterfaces)
            added_pd = True
        if not motors:
            _add_actuator(spec, _EFFORT_PREFIX + joint.name, joint.name).set_to_motor()
        joints.append(joint.name)
    if added_pd and spec.option.integrator == mujoco.mjtIntegrator.mjINT_EULER:
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    return JointPlan(tuple(joints), tuple(passive), tuple(unactuated), tuple(switched_off),
                     tuple(other_driven), tuple(replaced))


def _switch_off(actuators, joint):
    """Switch `actuators` (of joint name `joint`) off: a fixed gain of 0 and no bias (a
    muscle's too), no force; returns their names."""
    for actuator in actuators:
        actuator.gaintype, actuator.biastype = (mujoco.mjtGain.mjGAIN_FIXED,
                                                mujoco.mjtBias.mjBIAS_NONE)
        actuator.gainprm, actuator.biasprm = np.zeros(10), np.zeros(10)
    return [actuator.name or f'actuator on {joint}' for actuator in actuators]


def _add_actuator(spec, name, joint):
    """A new actuator on `joint`, unbounded, nothing inherited from default classes."""
    actuator = spec.add_actuator(name=name, target=joint, trntype=mujoco.mjtTrn.mjTRN_JOINT)
    actuator.inheritrange = 0.0
    actuator.gear[:] = (1.0, 0, 0, 0, 0, 0)
    actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
    return actuator


@dataclass(frozen=True)
class JointGains:
    """A position interface's gains: kp (N m/rad or N/m), kd (N m s/rad or N s/m), effort
    limit (N m or N; inf = none)."""
    kp: float
    kd: float
    effort: float


def inverse_mass_diagonal(model, data):
    """(nv,) diagonal of M^-1 in the current pose (after mj_forward)."""
    inverse = np.zeros((model.nv, model.nv))
    mujoco.mj_solveM(model, data, inverse, np.eye(model.nv))
    return np.diag(inverse).copy()


def default_gains(model, data, joint, timestep, inverse_diagonal):
    """kp, kd of a PD joint from the robot's mass, in the current pose (after mj_forward):

    kp = M g r / SAG_RAD for a hinge (r: the joint's reach: farthest body origin, centre of
    mass or geom centre of its subtree from its anchor, >= 1 cm), M g / SAG_M for a slide, M the mass of the robot (the joint's
    kinematic tree); then at most 4 I / dt^2 (omega dt <= 2; the step with implicit damping
    is stable up to omega dt = 2 + 2 sqrt 2), I = 1 / (M^-1)_jj the joint's
    effective inertia with everything else free (`inverse_diagonal`: of M^-1,
    inverse_mass_diagonal); kd = 2 sqrt(kp I) (critical damping)."""
    body = model.jnt_bodyid[joint]
    mass = model.body_subtreemass[model.body_rootid[body]]
    dof = model.jnt_dofadr[joint]
    inertia = 1.0 / inverse_diagonal[dof]
    if int(model.jnt_type[joint]) == mujoco.mjtJoint.mjJNT_HINGE:
        subtree = _subtree(model, body)
        points = np.vstack([data.xpos[subtree], data.xipos[subtree],
                            data.geom_xpos[np.isin(model.geom_bodyid, subtree)]])
        reach = max(0.01, float(np.max(np.linalg.norm(points - data.xanchor[joint], axis=1))))
        kp = mass * GRAVITY * reach / SAG_RAD
    else:
        kp = mass * GRAVITY / SAG_M
    kp = min(kp, 4.0 * inertia / timestep ** 2)
    return kp, 2.0 * math.sqrt(kp * inertia)


def _subtree(model, body):
    inside = np.zeros(model.nbody, dtype=bool)
    inside[body] = True
    for b in range(body + 1, model.nbody):
        inside[b] = inside[model.body_parentid[b]]
    return np.flatnonzero(inside)


class JointInterfaces:
    """The position and effort interfaces of the joints `joint_names` of a compiled model.

    position_actuators / effort_actuators: actuator ids (= ctrl indices), joint order.
    gains: {joint: JointGains} of the position interfaces. ranges: (joints, 2) each joint's
    range, rad or m, -inf / inf where it has none: where its targets are held.
    `set_mode('position'|'effort')` switches the position actuators on or off.
    """

    def __init__(self, model, data, joint_names, servos, timestep, effort_limits=None):
        self.model = model
        self.joint_names = tuple(joint_names)
        effort_limits = effort_limits or {}
        inverse_diagonal = inverse_mass_diagonal(model, data)
        position, effort, self.gains = [], [], {}
        for name in self.joint_names:
            joint = model.joint(name).id
            mine = [a for a in range(model.nu)
                    if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                    and model.actuator_trnid[a, 0] == joint]
            servo = [a for a in mine if _is_position_servo(
                model.actuator_gaintype[a], model.actuator_biastype[a],
                model.actuator_dyntype[a], model.actuator_gainprm[a], model.actuator_biasprm[a])]
            motor = [a for a in mine if _is_motor(  # (not one switched off: a gain of 0)
                model.actuator_gaintype[a], model.actuator_biastype[a],
                model.actuator_dyntype[a]) and model.actuator_gainprm[a, 0] != 0.0]
            position.append(servo[0])
            effort.append(motor[0])
            settings = servo_settings(servos, name)
            limit = settings.get('effort', self._model_limit(servo[0], motor[0],
                                                              effort_limits.get(name)))
            if model.actuator(servo[0]).name == _PD_PREFIX + name:
                kp, kd = default_gains(model, data, joint, timestep, inverse_diagonal)
            else:  # the model's own position servo: its gains unless the scene sets them
                kp = model.actuator_gainprm[servo[0], 0]
                kd = -model.actuator_biasprm[servo[0], 2]
            gains = JointGains(settings.get('kp', kp), settings.get('kd', kd), limit)
            self._set_gains(servo[0], gains.kp, gains.kd)
            self.gains[name] = gains
            if model.actuator(servo[0]).name == _PD_PREFIX + name and model.jnt_limited[joint]:
                model.actuator_ctrllimited[servo[0]] = 1  # (its target within the range)
                model.actuator_ctrlrange[servo[0]] = model.jnt_range[joint]
            if model.actuator(servo[0]).name == _PD_PREFIX + name or 'effort' in settings:
                self._limit(servo[0], limit)
            self._limit(motor[0], limit)
        joints = [model.joint(name).id for name in self.joint_names]
        self.ranges = np.where(model.jnt_limited[joints, None].astype(bool),
                               model.jnt_range[joints], [-np.inf, np.inf]).reshape(-1, 2)
        self.position_actuators = np.array(position, dtype=int)
        self.effort_actuators = np.array(effort, dtype=int)
        self._position_params = (model.actuator_gainprm[self.position_actuators].copy(),
                                 model.actuator_biasprm[self.position_actuators].copy())
        self.mode = 'position'

    def _model_limit(self, servo, motor, description_limit):
        """N m or N: the model's force bounds of the joint (its motor's ctrlrange x gear and
        forcerange, its position servo's forcerange), else the description's, else inf."""
        m = self.model
        bounds = [np.max(np.abs(m.actuator_forcerange[a])) for a in (servo, motor)
                  if m.actuator_forcelimited[a]]
        if m.actuator_ctrllimited[motor]:
            bounds.append(np.max(np.abs(m.actuator_ctrlrange[motor]))
                          * abs(m.actuator_gear[motor, 0]))
        if bounds:
            return float(min(bounds))
        return float(description_limit) if description_limit else math.inf

    def _limit(self, actuator, limit):
        if math.isfinite(limit):
            self.model.actuator_forcelimited[actuator] = 1
            self.model.actuator_forcerange[actuator] = (-limit, limit)

    def _set_gains(self, actuator, kp, kd):
        self.model.actuator_gainprm[actuator, 0] = kp
        self.model.actuator_biasprm[actuator, 1:3] = (-kp, -kd)

    def set_mode(self, mode):
        """'position': position actuators on (their gains); 'effort': off (zero force), so
        the motors alone act."""
        if mode == self.mode:
            return
        gain, bias = self._position_params
        on = 1.0 if mode == 'position' else 0.0
        self.model.actuator_gainprm[self.position_actuators] = gain * on
        self.model.actuator_biasprm[self.position_actuators] = bias * on
        self.mode = mode
