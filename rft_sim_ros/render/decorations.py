"""What is drawn on top of the model: the plates in the sand coloured by their stress, and
one arrow per leg for the ground force the sand applies to it. Shared by the video frames
(`frames`) and the live viewer (`viewer`), added to a mujoco.MjvScene as extra geoms.

Stress colours: |F| / area of a plate relative to STRESS_FULL_SCALE_DEPTH_M * zeta (the
stress of a plate pushed straight down that deep), on matplotlib's 'turbo' map (blue at no
stress, dark red at full scale and above), glowing (`PLATE_EMISSION`) through the sand. Force arrows: a leg carrying the robot's whole
weight gets an arrow ARROW_WEIGHT_LENGTH robot sizes long; lengths grow linearly with |F|.
"""
from dataclasses import dataclass

import mujoco
import numpy as np

from ..units import zeta_to_si

#: m: a plate pushed straight down this deep has the stress drawn at full colour.
STRESS_FULL_SCALE_DEPTH_M = 0.05
#: Where on matplotlib's 'turbo' map no stress lies (its darkest blues left out: a plate
#: is seen through the sand), and how much of its colour a plate emits (lit or not).
TURBO_FROM = 0.15
PLATE_EMISSION = 0.7
#: Robot sizes (`stage.Stage.robot_size`) of the arrow of a force equal to the robot's weight.
ARROW_WEIGHT_LENGTH = 0.6
#: Arrow colour (RGBA) and width (robot sizes).
ARROW_RGBA = (0.1, 0.8, 0.2, 1.0)
ARROW_WIDTH = 0.025
#: At most this many plates are drawn a frame, evenly chosen among the active ones (in
#: llvmpipe each costs some 0.17 ms: the hexapod's 1,450 would cost four times the rest of
#: the frame).
MAX_PLATES_DRAWN = 150
#: Plates are drawn as cubes at least this many robot sizes wide (a 1 mm plate is under a
#: pixel in a frame that shows the whole robot).
PLATE_MIN_SIZE = 0.02


@dataclass(frozen=True)
class Plates:
    """Plates to draw: positions (K, 3) m, world; rgba (K, 4) in [0, 1]; size (K,) m (the
    side of each plate's cube)."""
    positions: np.ndarray
    rgba: np.ndarray
    size: np.ndarray


def stress_colours(stress_pa, zeta):
    """(K, 4) RGBA of plate stresses (Pa) in sand of stiffness `zeta` (N/cm^3)."""
    from matplotlib import colormaps
    full = zeta_to_si(zeta) * STRESS_FULL_SCALE_DEPTH_M
    share = np.clip(np.asarray(stress_pa, float) / full, 0.0, 1.0)
    return colormaps['turbo'](TURBO_FROM + (1.0 - TURBO_FROM) * share)


def plates_from_forces(positions, forces, areas, zeta, robot_size):
    """`Plates` of active plates (positions m, forces N and areas m^2, as
    SandEngine.active_plates gives them), coloured by stress (`stress_colours`); at most
    MAX_PLATES_DRAWN of them, evenly chosen."""
    if len(areas) > MAX_PLATES_DRAWN:
        chosen = np.linspace(0, len(areas) - 1, MAX_PLATES_DRAWN).round().astype(int)
        positions, forces, areas = (np.asarray(a)[chosen] for a in (positions, forces, areas))
    areas = np.asarray(areas, float)
    stress = np.linalg.norm(np.asarray(forces, float), axis=1) / np.maximum(areas, 1e-12)
    size = np.maximum(np.sqrt(areas), PLATE_MIN_SIZE * robot_size)
    return Plates(np.asarray(positions, float), stress_colours(stress, zeta), size)


def add_plates(scene, plates):
    """Add the `Plates` to `scene` as cubes (as many as it has room for); returns how many
    were left out for want of room."""
    room = scene.maxgeom - scene.ngeom
    count = min(room, len(plates.size))
    identity = np.eye(3).ravel()
    for k in range(count):
        half = 0.5 * plates.size[k]
        mujoco.mjv_initGeom(scene.geoms[scene.ngeom], mujoco.mjtGeom.mjGEOM_BOX,
                            np.array([half, half, half]), plates.positions[k], identity,
                            plates.rgba[k].astype(np.float32))
        scene.geoms[scene.ngeom].emission = PLATE_EMISSION
        scene.ngeom += 1
    return len(plates.size) - count


def add_force_arrows(scene, points, forces, weight, robot_size):
    """Add an arrow per leg to `scene`: from its point (m, world) along its ground force (N,
    world axes), scaled so that `weight` (N, the robot's) is ARROW_WEIGHT_LENGTH robot sizes;
    forces under a thousandth of the weight are left out."""
    scale = ARROW_WEIGHT_LENGTH * robot_size / max(weight, 1e-9)
    width = ARROW_WIDTH * robot_size
    for point, force in zip(points, forces):
        force = np.asarray(force, float)
        if scene.ngeom >= scene.maxgeom or np.linalg.norm(force) < 1e-3 * weight:
            continue
        geom = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3),
                            np.eye(3).ravel(), np.array(ARROW_RGBA, np.float32))
        start = np.asarray(point, float)
        mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_ARROW, width, start,
                             start + scale * force)
        scene.ngeom += 1


def robot_weight(model):
    """N: the weight of the model's moving bodies (|gravity| times their mass)."""
    moving = model.body_weldid != 0
    return float(np.linalg.norm(model.opt.gravity) * model.body_mass[moving].sum())
