"""Names and geometry of the bundled hexapod, models/hexapod.xml: the RFT-SiM crab hexapod
(see docs/hexapod.md).

The constants here mirror the MJCF (test/test_hexapod_model.py checks them against it).
Frames: base_link, +x along the body's long axis, +y left, +z up, origin at the centre of the
body plate (the hip plane). The robot walks sideways, towards +y. SI units.
"""
import numpy as np

from rft_sim_ros.scenes.leg_kinematics import LateralLegs

#: MJCF files, relative to the package's models/ folder.
MODEL_FILE = 'hexapod.xml'
RIGID_FLOOR_SCENE = 'hexapod_rigid_floor.xml'

#: Legs: L = left (+y), R = right (-y); 1 = front (x = +0.14 m), 2 = middle, 3 = rear.
LEG_NAMES = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')

#: Joint (and position-actuator) order used for arrays: knee then ankle, leg by leg.
JOINT_NAMES = tuple(f'{leg}_{joint}' for leg in LEG_NAMES for joint in ('knee', 'ankle'))

#: Bodies of one leg, proximal to distal: the proximal segment (fixed to base_link, from the
#: plate's edge to the knee axis), the mid segment (moved by the knee), the dactyl (moved by
#: the ankle). Per-leg wrenches sum over these.
LEG_BODIES = {leg: (f'{leg}_coxa', f'{leg}_mid', f'{leg}_dactyl') for leg in LEG_NAMES}

#: Bodies to give the RFT engine: the dactyls always touch the sand; the mid segments (the
#: ankle is 0.106 m above the foot tip in the neutral stance) reach it in very loose sand.
SAND_BODIES = tuple(f'{leg}_{part}' for leg in LEG_NAMES for part in ('dactyl', 'mid'))

#: Body (the 1 kg box on the plate, its centre 0.06 m above the plate's) whose mass a scene
#: raises to add a payload of m kg:  spec.body(PAYLOAD_BODY).mass += m  (mujoco.MjSpec).
PAYLOAD_BODY = 'payload'

#: Mass of the unloaded robot, kg: plate 1 + box 1 + 6 x (0.10 + 0.14 + 0.10).
MASS_KG = 4.04

#: Foot tip of each leg, a site '<leg>_foot' on its dactyl.
FOOT_SITES = tuple(f'{leg}_foot' for leg in LEG_NAMES)

_LEG_X = {'1': 0.14, '2': 0.0, '3': -0.14}
_SIDE = {'L': 1.0, 'R': -1.0}

#: Kinematics of the six legs (matches models/hexapod.xml): knee axes 0.275 m and ankle axes
#: 0.35 m out from the centre line in the hip plane; the dactyl tip 0.108 m beyond and
#: 0.015 m below the ankle axis in the zero pose (0.458 m out). Neutral stance: each foot tip
#: 0.176 m below its knee axis (the published gait's height), straight under it.
LEGS = LateralLegs(
    names=LEG_NAMES,
    knee_xyz=np.array([[_LEG_X[leg[1]], _SIDE[leg[0]] * 0.275, 0.0] for leg in LEG_NAMES]),
    side=np.array([_SIDE[leg[0]] for leg in LEG_NAMES]),
    mid_length=0.075,
    tip_out=0.108,
    tip_down=0.015,
    knee_range=(-1.75, 0.35),
    ankle_range=(-1.92, 0.35),
    neutral_out=0.0,
    neutral_down=0.176,
)

#: Alternating tripod: R1 L2 R3 in phase 0, L1 R2 L3 half a cycle later.
TRIPOD_PHASES = {'R1': 0.0, 'L2': 0.0, 'R3': 0.0, 'L1': 0.5, 'R2': 0.5, 'L3': 0.5}
