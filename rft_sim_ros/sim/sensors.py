"""What a robot's sensors read: an IMU, foot contacts per leg, the model's own MJCF sensors.

ROS-free. `Sensors` is built once per Simulation from the scene's `sensors` keys and reads
the current state into a `SensorReadings` at each publish cycle (`Simulation.state`), from
the same MuJoCo data as the rest of the state (`SimState`): the kinematics and velocities of
the last step's start, its accelerations. All SI; frames named per field.

* IMU (`sensors.imu`): at the model's IMU frame: the site its MJCF imu sensors
  (accelerometer, gyro, framequat) sit on, else a body (URDF link) named imu*, *_imu or
  *_imu_link, else the base body; `sensors.imu_frame` names a site or body instead.
  orientation: the frame's in the world (odom); angular velocity: rad/s in the IMU frame;
  linear acceleration: the specific force an accelerometer reads, m/s^2 in the IMU frame
  (the frame origin's acceleration minus gravity: +9.81 up at rest). Optional white noise
  (`imu_noise.gyro_std` rad/s, `accel_std` m/s^2) and constant biases (`gyro_bias`,
  `accel_bias`, 3 values each), off by default, seeded (`imu_noise.seed`); covariances are
  the noise variances on the diagonal (0: exact; orientation: always exact).
* Foot contacts (`sensors.contacts`): per leg, the normal force N on its foot (the sand
  force on the leg's last sand body, its reference point, the publish-period mean, along
  the sand surface's upward normal under that point) and stance = normal force >
  `sensors.contact_threshold` N (default: 5 % of the robot's weight over the number of
  legs). The foot alone: a shank or mid segment resting in the sand loads the leg's wrench
  (/rft/<leg>/wrench) but is no stance (the hexapod's rear mid segments drag through the
  sand while their feet swing).
* Model sensors (`sensors.model_sensors`): every named `<sensor>` of the MJCF, its values as
  MuJoCo computes them (mjData.sensordata; the model's units). MuJoCo's touch sensors feel
  rigid contacts only, not the sand (its force reaches force/torque sensors, through
  xfrc_applied, and the foot contacts above).
"""
import fnmatch
from dataclasses import dataclass
from typing import Optional, Tuple

import mujoco
import numpy as np

#: Body names that make a body the IMU frame (a URDF's IMU link).
IMU_BODY_PATTERNS = ('imu*', '*_imu', '*_imu_link')
#: Default stance threshold: this share of the robot's weight per leg.
CONTACT_SHARE = 0.05
_IMU_SENSORS = {int(kind) for kind in (mujoco.mjtSensor.mjSENS_ACCELEROMETER,
                                        mujoco.mjtSensor.mjSENS_GYRO,
                                        mujoco.mjtSensor.mjSENS_FRAMEQUAT)}


@dataclass(frozen=True)
class ImuReading:
    """One IMU sample. frame: its frame's name; quaternion_wxyz: (4,) its orientation in odom;
    angular_velocity: (3,) rad/s, IMU axes; linear_acceleration: (3,) m/s^2 specific force,
    IMU axes; *_covariance: (9,) row-major 3x3 (rad^2, (rad/s)^2, (m/s^2)^2)."""
    frame: str
    quaternion_wxyz: np.ndarray
    angular_velocity: np.ndarray
    linear_acceleration: np.ndarray
    orientation_covariance: np.ndarray
    angular_velocity_covariance: np.ndarray
    linear_acceleration_covariance: np.ndarray


@dataclass(frozen=True)
class FootContacts:
    """Per leg (`legs` order): stance flags and normal forces (N, along the surface normal)."""
    legs: Tuple[str, ...]
    stance: np.ndarray
    normal_force: np.ndarray


@dataclass(frozen=True)
class ModelSensor:
    """A named MJCF sensor: `kind` (MuJoCo's type name in lower case: 'touch', 'force',
    'gyro', ...), `frame` (the name of the site or body it is attached to, '' if none) and
    its `values` (mjData.sensordata, the model's units)."""
    name: str
    kind: str
    frame: str
    values: np.ndarray


@dataclass(frozen=True)
class SensorReadings:
    """The readings of one publish cycle: each None (or empty) when not enabled."""
    imu: Optional[ImuReading]
    contacts: Optional[FootContacts]
    model_sensors: Tuple[ModelSensor, ...] = ()


@dataclass(frozen=True)
class SensorLayout:
    """Which readings a run publishes: imu (and its topic), contacts (per leg of `legs`),
    model sensors (name, kind, frame of each, in model order)."""
    imu_topic: Optional[str]
    contact_legs: Optional[Tuple[str, ...]]
    model_sensors: Tuple[Tuple[str, str, str], ...] = ()


def scene_settings(values):
    """The `Sensors` settings of a scene's effective values (SceneConfig.values, by dotted
    key): {leaf: value} of the sensors.* keys, imu_noise a {leaf: value} of its own."""
    noise = 'sensors.imu_noise.'
    settings = {key[len('sensors.'):]: value for key, value in values.items()
                if key.startswith('sensors.') and not key.startswith(noise)}
    settings['imu_noise'] = {key[len(noise):]: value for key, value in values.items()
                             if key.startswith(noise)}
    return settings


def _object_name(model, objtype, objid):
    if objid < 0:
        return ''
    return mujoco.mj_id2name(model, objtype, objid) or ''


def imu_frame(model, base_body, name=None):
    """(mjtObj, id, name) of the IMU frame of `model` (module docstring); `name`: a site or
    body to use instead (ValueError if it is neither)."""
    if name:
        for objtype in (mujoco.mjtObj.mjOBJ_SITE, mujoco.mjtObj.mjOBJ_BODY):
            objid = mujoco.mj_name2id(model, objtype, name)
            if objid >= 0:
                return (mujoco.mjtObj.mjOBJ_XBODY if objtype == mujoco.mjtObj.mjOBJ_BODY
                        else objtype), objid, name
        raise ValueError(f'{name!r} is neither a site nor a body of the model')
    for s in range(model.nsensor):
        if int(model.sensor_type[s]) in _IMU_SENSORS and \
                int(model.sensor_objtype[s]) == int(mujoco.mjtObj.mjOBJ_SITE):
            site = int(model.sensor_objid[s])
            return mujoco.mjtObj.mjOBJ_SITE, site, _object_name(model, mujoco.mjtObj.mjOBJ_SITE,
                                                                 site)
    for b in range(1, model.nbody):
        body = model.body(b).name
        if any(fnmatch.fnmatchcase(body.lower(), p) for p in IMU_BODY_PATTERNS):
            return mujoco.mjtObj.mjOBJ_XBODY, b, body
    return mujoco.mjtObj.mjOBJ_XBODY, base_body, model.body(base_body).name


def _three(values, what):
    out = np.zeros(3) if values is None else np.array(values, dtype=float).reshape(-1)
    if out.shape != (3,) or not np.all(np.isfinite(out)):
        raise ValueError(f'{what} must be 3 finite numbers, got {values!r}')
    return out


class Imu:
    """The IMU of a model at frame (objtype, objid, name) (`imu_frame`), with noise settings
    {gyro_std, accel_std, gyro_bias, accel_bias, seed} (missing: none)."""

    def __init__(self, model, frame, noise=None):
        noise = noise or {}
        self._model = model
        self._objtype, self._objid, self.frame = frame
        self._gyro_std = float(noise.get('gyro_std') or 0.0)
        self._accel_std = float(noise.get('accel_std') or 0.0)
        self._gyro_bias = _three(noise.get('gyro_bias'), 'sensors.imu_noise.gyro_bias')
        self._accel_bias = _three(noise.get('accel_bias'), 'sensors.imu_noise.accel_bias')
        self._rng = np.random.default_rng(noise.get('seed'))
        self._covariances = (np.zeros(9), np.diag([self._gyro_std ** 2] * 3).ravel(),
                             np.diag([self._accel_std ** 2] * 3).ravel())
        self._vector = np.empty(6)

    def read(self, data):
        """ImuReading of `data` (after a step: its kinematics, velocities and qacc)."""
        model, objtype, objid = self._model, self._objtype, self._objid
        if objtype == mujoco.mjtObj.mjOBJ_SITE:
            quaternion = np.empty(4)
            mujoco.mju_mat2Quat(quaternion, data.site_xmat[objid])
        else:
            quaternion = data.xquat[objid].copy()
        mujoco.mj_objectVelocity(model, data, objtype, objid, self._vector, 1)
        gyro = self._vector[:3].copy()
        mujoco.mj_rnePostConstraint(model, data)  # (cacc: the accelerations, gravity in)
        mujoco.mj_objectAcceleration(model, data, objtype, objid, self._vector, 1)
        accel = self._vector[3:].copy()
        if self._gyro_std:
            gyro += self._rng.normal(0.0, self._gyro_std, 3)
        if self._accel_std:
            accel += self._rng.normal(0.0, self._accel_std, 3)
        return ImuReading(self.frame, quaternion, gyro + self._gyro_bias,
                          accel + self._accel_bias, *self._covariances)


class Sensors:
    """The sensors a scene asks for (`settings`: the scene's sensors.* values by leaf name:
    imu, imu_topic, imu_frame, imu_noise, contacts, contact_threshold, model_sensors) on a
    compiled `model` whose base body is `base_body` (id) and legs `leg_names`, over the sand
    `surface` (a `sand.surface.Surface`; its normals are looked up at every reading unless it
    is level everywhere for good: not `deformable` and no slope)."""

    def __init__(self, model, base_body, leg_names, settings, surface, deformable):
        self._model = model
        self._surface = surface
        self._level = not deformable and surface.steepest_deg() == 0.0
        self.imu = None
        self.imu_topic = settings.get('imu_topic')
        if settings.get('imu'):
            self.imu = Imu(model, imu_frame(model, base_body, settings.get('imu_frame')),
                           settings.get('imu_noise'))
        self.contact_legs = tuple(leg_names) if settings.get('contacts') else None
        threshold = settings.get('contact_threshold')
        if threshold is None and leg_names:
            weight = model.body_subtreemass[model.body_rootid[base_body]] * \
                np.linalg.norm(model.opt.gravity)
            threshold = CONTACT_SHARE * weight / len(leg_names)
        self.contact_threshold = threshold
        self._model_sensors = []
        if settings.get('model_sensors'):
            for s in range(model.nsensor):
                name = model.sensor(s).name
                if not name:
                    continue
                kind = mujoco.mjtSensor(int(model.sensor_type[s])).name[len('mjSENS_'):].lower()
                frame = _object_name(model, int(model.sensor_objtype[s]),
                                     int(model.sensor_objid[s]))
                start = int(model.sensor_adr[s])
                self._model_sensors.append((name, kind, frame,
                                            slice(start, start + int(model.sensor_dim[s]))))

    @property
    def layout(self):
        """The `SensorLayout` of what `read` gives."""
        return SensorLayout(imu_topic=self.imu_topic if self.imu else None,
                            contact_legs=self.contact_legs,
                            model_sensors=tuple((n, k, f) for n, k, f, _ in self._model_sensors))

    @property
    def active(self):
        return bool(self.imu or self.contact_legs is not None or self._model_sensors)

    def read(self, data, legs, feet, stepped=True):
        """SensorReadings of `data` now; legs: the state's LegWrenches (their points); feet:
        (legs, 3) the mean sand force on each leg's foot, N, world axes; stepped: whether a
        step has been taken since the simulation (re)started. Before one, no IMU reading:
        the state's accelerations are not yet those of a step with the sand's forces (the
        model's forward dynamics of the pose as set: a spike of many g), so the IMU's first
        sample comes with the first state after a step."""
        imu = self.imu.read(data) if self.imu is not None and stepped else None
        contacts = None
        if self.contact_legs is not None:
            forces = np.asarray(feet, dtype=float).reshape(-1, 3)
            if self._level:
                force = forces[:, 2]
            else:
                points = np.array([leg.point for leg in legs]).reshape(-1, 3)
                normals = self._surface.normal(points[:, 0], points[:, 1])
                force = np.einsum('ij,ij->i', forces, normals)
            contacts = FootContacts(self.contact_legs, force > self.contact_threshold, force)
        model_sensors = tuple(ModelSensor(name, kind, frame, data.sensordata[span].copy())
                              for name, kind, frame, span in self._model_sensors)
        return SensorReadings(imu, contacts, model_sensors)
