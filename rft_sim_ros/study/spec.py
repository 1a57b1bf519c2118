"""Study files: a scene plus the values to vary, loaded, validated and expanded into runs.

A study file (YAML):

    scene: hexapod                 # bundled scene name, a scene YAML or a robot file
                                   # (MJCF, URDF, xacro; relative to the study file)
    set: {cycles: 2}               # optional: fixed overrides for every run (as --set)
    duration: 3.0                  # optional: sim time per run, s (default: the scene's)
    vary: {zeta: [1.0, 3.75], payload: [0.0, 1.0]}   # grid: every combination
    repeats: 1                     # optional: each combination this many times
    metrics: [forward_distance_m, mean_sinkage_m]

`vary` takes three forms: a mapping of key -> list of values (a grid, every combination);
a list of mappings (explicit runs); or `{sample: {count: N, seed: S, ranges: {key: [low,
high], ...}}}` (N random runs drawn uniformly within each range; integers when both bounds
are integers; `log: [keys]` draws those keys uniformly in log space). Keys are anything
`rft-sim run --set` accepts (`zeta`, `timestep`, `rft.plates_per_body`, a scene param...).
Every run's scene is loaded and validated here, before any run starts.
"""
import functools
import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ..robot.model_files import mjcf_files
from ..sand.deformable import bed_bytes, check_memory
from ..sand.surface import HeightGrid, surface_from_settings
from ..sand.zeta_map import zeta_map_from_settings
from ..scenes.config import SceneError, anchor_paths, bundled_scenes, load_scene
from ..scenes.schema import load_yaml
from .cost import run_cost

_KNOWN = {'scene', 'set', 'duration', 'vary', 'repeats', 'metrics', 'description'}


class StudyError(SceneError):
    """A study file cannot be loaded or is invalid; the message says what to fix."""


@dataclass(frozen=True)
class Run:
    """One run of a study: its id (folder name under DIR/runs), the varied values, the repeat
    index (0-based), the overrides it hands load_scene (fixed `set` + varied values), its
    expected relative cost (`cost.run_cost`: runs go out dearest first), the files it
    reads (`files_read`) and the bytes its deformable bed holds (0 without one)."""
    run_id: str
    varied: dict
    repeat: int
    overrides: dict
    cost: float = 1.0
    files: tuple = ()
    bed_bytes: float = 0.0


@dataclass(frozen=True)
class Study:
    """A validated study. scene: bundled name or absolute path of a scene or robot file;
    fixed: overrides for every run; duration: s or None (the scene's); keys: the varied keys
    in column order; runs: the Runs; source: the study file's mapping."""
    scene: str
    fixed: dict
    duration: float
    keys: tuple
    runs: tuple
    repeats: int
    metrics: tuple
    source: dict


def load_study(path):
    """Read, validate and expand the study file at `path`. Raises StudyError."""
    path = Path(path)
    try:
        raw = load_yaml(path.read_text())
    except OSError as error:
        raise StudyError(f'cannot read study file {path}: {error.strerror}') from None
    except yaml.YAMLError as error:
        raise StudyError(f'{path}: not valid YAML: {error}') from None
    return study_from_mapping(raw, base=path.parent, where=str(path))


def study_from_mapping(raw, base=Path('.'), where='study'):
    """Validate and expand a study given as a mapping (the content of a study file); scene
    paths, and files named in set and vary (`anchor_paths`), are relative to `base`. Raises
    StudyError."""
    if not isinstance(raw, dict):
        raise StudyError(f'{where}: a study file must hold a mapping')
    unknown = sorted(set(raw) - _KNOWN)
    if unknown:
        raise StudyError(f'{where}: unknown keys {unknown} (known: {sorted(_KNOWN)})')
    scene = raw.get('scene')
    if not isinstance(scene, str) or not scene:
        raise StudyError(f'{where}: missing scene (a bundled scene name, a scene YAML or a '
                         'robot file)')
    beside = Path(base) / scene
    if not Path(scene).is_absolute() and beside.is_file():  # a file next to the study file
        scene = str(beside.resolve())
    fixed = raw.get('set') or {}
    if not isinstance(fixed, dict) or not all(isinstance(k, str) for k in fixed):
        raise StudyError(f'{where}: set must map scene keys to values')
    duration = raw.get('duration')
    if duration is not None and (
            isinstance(duration, bool) or not isinstance(duration, (int, float))
            or not (math.isfinite(duration) and duration > 0)):
        raise StudyError(f'{where}: duration must be a number of seconds > 0, got {duration!r}')
    repeats = raw.get('repeats', 1)
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise StudyError(f'{where}: repeats must be a positive integer, got {repeats!r}')
    metrics = raw.get('metrics')
    if (not isinstance(metrics, list) or not metrics
            or not all(isinstance(m, str) and m for m in metrics)):
        raise StudyError(f'{where}: metrics must list the summary metrics to collect, '
                         'e.g. [forward_distance_m, mean_sinkage_m]')
    points = expand(raw.get('vary'), where)
    keys = tuple(dict.fromkeys(k for point in points for k in point))
    width = len(str(len(points) * repeats - 1))
    costs, files, beds = {}, {}, {}
    for point in points:
        overrides = anchor_paths({**fixed, **point}, base)  # files: from the study's folder
        key = _frozen(overrides)
        if key not in costs:
            try:
                loaded = load_scene(scene, overrides)
                check_terrain(loaded)
                costs[key] = run_cost(loaded, duration)
                files[key] = files_read(scene, loaded)
                bed = loaded.deformable
                beds[key] = bed_bytes(bed['size'], bed['cell']) if bed.get('enabled') else 0.0
            except (SceneError, ValueError) as error:
                raise StudyError(f'{where}: run with {overrides}: {error}') from None
    runs = []
    for i, point in enumerate(points):
        overrides = anchor_paths({**fixed, **point}, base)
        key = _frozen(overrides)
        for repeat in range(repeats):
            index = i * repeats + repeat
            runs.append(Run(f'{index:0{width}d}', point, repeat, overrides, costs[key],
                            files[key], beds[key]))
    return Study(scene=scene, fixed=dict(fixed), duration=None if duration is None
                 else float(duration), keys=keys, runs=tuple(runs), repeats=repeats,
                 metrics=tuple(metrics), source=raw)


def files_read(scene, loaded):
    """The files (absolute paths, sorted) a run of `scene` (a bundled scene's name or a file)
    reads as `loaded` (its SceneConfig) resolved them: the scene file, the model (an MJCF
    with the files it includes and its assets: meshes, a height field's image,
    `model_files.mjcf_files`), a height grid and a zeta map file; a resumed study compares
    them by SHA-256."""
    scenes = bundled_scenes()
    model = loaded.model_path
    candidates = (scenes.get(scene, scene), model, loaded.surface.get('file'),
                  (loaded.zeta_map or {}).get('file'),
                  *(mjcf_files(str(model)) if str(model).endswith('.xml') else ()))
    return tuple(sorted({str(Path(p).resolve()) for p in candidates
                         if p is not None and Path(p).is_file()}))


def check_terrain(scene):
    """Read the terrain files of `scene` (a SceneConfig) and check its deformable bed's size
    as the Simulation will, so that a study refuses a bad one before any run starts; the
    model's own hfield is read from its MJCF (`_check_hfield`). Raises ValueError."""
    if scene.surface.get('type', 'plane') == 'hfield':
        _check_hfield(str(scene.model_path), scene.surface.get('geom'))
    else:
        surface_from_settings(scene.surface, scene.surface_height)
    zeta_map_from_settings(scene.zeta_map)
    bed = scene.deformable
    if bed.get('enabled'):
        check_memory(bed['size'], bed['cell'])


@functools.lru_cache(maxsize=None)
def _check_hfield(model_path, geom):
    """Read the hfield geom `geom` of the MJCF at `model_path` as the Simulation will (a
    missing or tilted one raises ValueError), compiled once per model and geom. A model
    that is no MJCF, or that compiles only with the scene's edits, is left to its runs."""
    if not model_path.endswith('.xml'):
        return
    import mujoco
    try:
        model = mujoco.MjModel.from_xml_path(model_path)
    except ValueError:
        return
    HeightGrid.from_mjcf_hfield(model, geom)


def expand(vary, where='study'):
    """The points (list of {key: value}) a `vary` entry describes (see module docstring)."""
    if isinstance(vary, list):
        if not vary or not all(isinstance(p, dict) and p for p in vary):
            raise StudyError(f'{where}: vary as a list must hold one mapping per run')
        return [dict(p) for p in vary]
    if not isinstance(vary, dict) or not vary:
        raise StudyError(f'{where}: vary must be a grid {{key: [values]}}, a list of runs '
                         '[{key: value}], or {sample: {count, seed, ranges}}')
    if set(vary) == {'sample'}:
        return _samples(vary['sample'], where)
    for key, values in vary.items():
        if not isinstance(values, list) or not values:
            raise StudyError(f'{where}: vary.{key} must be a non-empty list of values')
    keys = list(vary)
    return [dict(zip(keys, combo)) for combo in itertools.product(*vary.values())]


def _samples(spec, where):
    if not isinstance(spec, dict) or set(spec) - {'count', 'seed', 'ranges', 'log'}:
        raise StudyError(f'{where}: vary.sample takes count, seed, ranges and log')
    count, seed, ranges = spec.get('count'), spec.get('seed'), spec.get('ranges')
    log = spec.get('log') or []
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise StudyError(f'{where}: vary.sample.count must be a positive integer')
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise StudyError(f'{where}: vary.sample.seed must be an integer >= 0 (samples are '
                         'reproducible)')
    if not isinstance(ranges, dict) or not ranges:
        raise StudyError(f'{where}: vary.sample.ranges must map keys to [low, high]')
    for key, bounds in ranges.items():
        if (not isinstance(bounds, list) or len(bounds) != 2
                or not all(isinstance(b, (int, float)) and not isinstance(b, bool)
                           and math.isfinite(b) for b in bounds) or not bounds[0] < bounds[1]):
            raise StudyError(f'{where}: vary.sample.ranges.{key} must be [low, high] with '
                             f'low < high, got {bounds!r}')
        if key in log and not bounds[0] > 0:
            raise StudyError(f'{where}: vary.sample.ranges.{key}: log sampling needs low > 0')
    if not isinstance(log, list) or not set(log) <= set(ranges):
        raise StudyError(f'{where}: vary.sample.log must list keys of ranges')
    rng = np.random.default_rng(seed)
    columns = {}
    for key, (low, high) in ranges.items():
        if isinstance(low, int) and isinstance(high, int) and key not in log:
            columns[key] = [int(v) for v in rng.integers(low, high, count, endpoint=True)]
        elif key in log:
            columns[key] = [float(v) for v in np.exp(rng.uniform(np.log(low), np.log(high),
                                                                   count))]
        else:
            columns[key] = [float(v) for v in rng.uniform(low, high, count)]
    return [{key: columns[key][i] for key in ranges} for i in range(count)]


def _frozen(mapping):
    return tuple(sorted((k, repr(v)) for k, v in mapping.items()))
