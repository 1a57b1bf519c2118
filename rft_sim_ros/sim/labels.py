"""Readable names, with units, of the keys a user meets in plots and pages: scene keys
(`--set` names, dotted), summary metrics (generic_metrics, a scenario's metrics) and
time-series columns.

`label(key)` looks the key up in KNOWN; otherwise it reads the unit from the key's own
unit word (the project's naming: _m, _mps, _N, _s, ...), turns underscores and dots into spaces
and keeps what follows the unit (a body or leg name) after a colon; a key with no unit
suffix is only made readable, never given a unit it does not state.
"""
import re
from pathlib import PurePath

from ..scenes.config import GENERIC_STEMS, robot_file_name

#: Keys whose readable name is not their spelled-out key.
KNOWN = {
    'zeta': 'sand stiffness zeta (N/cm³)',
    'zeta_final': 'final sand stiffness zeta (N/cm³)',
    'payload': 'payload (kg)',
    'mass': 'mass (kg)',
    'timestep': 'timestep (s)',
    'timestep_s': 'timestep (s)',
    'frequency': 'gait frequency (Hz)',
    'cycles': 'gait cycles',
    'drop_height': 'drop height (m)',
    'settle_time': 'settling time (s)',
    'stance_fraction': 'stance fraction',
    'rft.plates_per_body': 'plates per sand body',
    'plates_per_body': 'plates per sand body',
    'sand.surface_height': 'sand surface height (m)',
    'servo_kp': 'servo stiffness kp (N m/rad)',
    'real_time_factor': 'real-time factor (sim s per wall s)',
    'plates_active_mean': 'plates in the sand (mean)',
    'implicit_solves_per_step': 'implicit solves per step',
    'total_mass_kg': 'total mass (kg)',
    'backward_fraction': 'share of time moving backward',
}

#: Unit suffixes of the project's key names -> the unit as written on an axis.
UNITS = {'mps': 'm/s', 'm': 'm', 'mm': 'mm', 's': 's', 'N': 'N', 'Nm': 'N m', 'rad': 'rad',
         'deg': 'deg', 'kg': 'kg', 'Hz': 'Hz', 'Pa': 'Pa', 'J': 'J', 'W': 'W'}

_INDEX = re.compile(r'^(.*)\[(\d+)\]$')


def _words(text):
    return text.replace('.', ' ').replace('_', ' ').strip()


def label(key):
    """The readable name of `key` with its unit in brackets (module docstring), e.g.
    'forward_distance_m' -> 'forward distance (m)', 'max_sinkage_m_L1_dactyl' ->
    'max sinkage (m): L1_dactyl', 'base_displacement_xyz_m[0]' -> 'base displacement x (m)'."""
    key = str(key)
    if key in KNOWN:
        return KNOWN[key]
    indexed = _INDEX.match(key)
    if indexed:
        base, i = indexed.group(1), int(indexed.group(2))
        if '_xyz_' in f'{base}_' and i < 3:
            return label(base.replace('_xyz', '_' + 'xyz'[i], 1))
        return f'{label(base)} [{i}]'
    parts = key.split('_')
    for at in range(1, len(parts)):  # the first unit word after a name; a body name follows
        if parts[at] in UNITS:
            name = _words('_'.join(parts[:at]))
            rest = '_'.join(parts[at + 1:])
            return f'{name} ({UNITS[parts[at]]})' + (f': {rest}' if rest else '')
    return _words(key) or key


def _stem(path):
    return PurePath(path).name.split('.')[0]


def robot_name(summary):
    """The robot a run's summary ran: the model's own name and its file, e.g. 'hexapod
    (hexapod.xml)', 'go2 scene (unitree_go2/scene.xml)'; a file whose stem says nothing
    (GENERIC_STEMS) with its folder."""
    robot = summary.get('robot_model') or {}
    path = robot.get('file') or (summary.get('scene_config') or {}).get('model') or ''
    file = PurePath(path).name
    if _stem(path) in GENERIC_STEMS and PurePath(path).parent.name:
        file = f'{PurePath(path).parent.name}/{file}'
    name = robot.get('name') or ''
    if not file:
        return name or 'robot'
    return f'{name} ({file})' if name and name != _stem(path) else file


def run_name(summary):
    """A run's heading: the robot (`robot_name`), and the scene when the run came from a
    scene file (the scene of a bare robot file, scenario external and named after the file,
    is not named again)."""
    config = summary.get('scene_config') or {}
    robot = summary.get('robot_model') or {}
    path = robot.get('file') or config.get('model') or ''
    scene = summary.get('scene') or ''
    if not scene or (scene == robot_file_name(path) and config.get('scenario') == 'external'):
        return robot_name(summary)
    return f'{robot_name(summary)} in scene {scene}'
