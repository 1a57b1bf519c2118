"""Cold starts: the notice that the kernels compile (shown exactly when numba's cache lacks
them), and kernels compiled into the cache by a second process (`BackgroundCompile`)."""
import importlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from rft_sim_ros.kernel_cache import (KERNEL_MODULES, PACKAGE, forget_stale, is_cached,
                                      kernel_sources, module_kernels, sources_fingerprint)
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation, compile_notice
from rft_sim_ros.warmup import cached_kernels

_PROBE = ('from rft_sim_ros.scenes.config import load_scene\n'
          'from rft_sim_ros.sim.simulation import compile_notice\n'
          'print(compile_notice(load_scene("plate_drop")))\n')


def test_an_empty_cache_gets_the_notice_without_a_figure(tmp_path):
    """A first run after install has measured nothing on this machine: no estimate."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, '-c', _PROBE], env=env, capture_output=True,
                          text=True, check=True, timeout=120)
    assert done.stdout.strip() == 'compiling kernels, first run only'


_RECORDED_PROBE = '''
from rft_sim_ros.kernel_cache import record_cold_start
from rft_sim_ros.sand import implicit_solve
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import compile_notice
every = "gather_plane implicit_plate_forces implicit_step_plain"
record_cold_start(implicit_solve.implicit_step_plain, every, 41.7, 80.2)
record_cold_start(implicit_solve.implicit_step_plain, "gather_plane", 3.2, 3.1)
print(compile_notice(load_scene("plate_drop")))
'''


def test_a_recorded_cold_start_of_the_same_kernels_gives_the_estimate(tmp_path):
    """The estimate is the last measured start that compiled exactly the kernels the cache
    lacks now (not that of a start that compiled only one of them)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, '-c', _RECORDED_PROBE], env=env,
                          capture_output=True, text=True, check=True, timeout=120)
    assert done.stdout.strip() == 'compiling kernels, first run only, ~42 s as here last time'


def test_a_filled_cache_gets_none():
    for overrides in ({}, {'rft.low_velocity.method': 'ema'}, {'sand.surface.type': 'slope'},
                      {'sand.deformable.enabled': True}):
        scene = load_scene('plate_drop', overrides)
        Simulation(scene)               # loads (or compiles and caches) its kernels
        assert compile_notice(scene) is None, overrides


_OWN_SURFACE_PROBE = '''
import json
from rft_sim_ros.kernel_cache import is_cached, last_cold_start
from rft_sim_ros.sand import gather, implicit_solve
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation, compile_notice
slope = load_scene("plate_drop", {"sand.surface.type": "slope"})
Simulation(slope)
kernels = ("gather_plane", "gather_slope", "gather_grid", "gather_deformable")
every = "gather_slope implicit_plate_forces implicit_step_plain"
print(json.dumps({"cached": {name: is_cached(getattr(gather, name)) for name in kernels},
                  "slope": compile_notice(slope),
                  "plane": compile_notice(load_scene("plate_drop")),
                  "recorded": last_cold_start(implicit_solve.implicit_step_plain, every)}))
'''


@pytest.mark.slow  # (a whole cold compile of the implicit step in a fresh cache: minutes)
def test_a_scene_compiles_the_gather_kernel_of_its_own_surface_only(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, '-c', _OWN_SURFACE_PROBE], env=env,
                          capture_output=True, text=True, check=True, timeout=300)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result['cached'] == {'gather_plane': False, 'gather_slope': True,
                                'gather_grid': False, 'gather_deformable': False}
    assert result['slope'] is None  # its kernels are there now
    assert result['plane'] == 'compiling kernels, first run only'  # the plane's gather is not
    recorded = result['recorded']  # what compiling them took, measured
    assert recorded['wall_s'] > 0 and recorded['cpu_s'] > 0, recorded


_BACKGROUND_PROBE = '''
import json, numpy as np
from rft_sim_ros.kernel_cache import BackgroundCompile, is_cached, load
from rft_sim_ros.sand import mujoco_terms
kernel, signature = mujoco_terms.implicit_mass, "(float64[:, ::1], float64[::1], float64)"
before = is_cached(kernel)
job = BackgroundCompile([(kernel, signature)])
done, why = job.wait()
after = is_cached(kernel)
load(kernel, signature)  # loads what the child compiled: no compile here
mass = np.eye(2)
kernel(mass, np.array([1.0, 2.0]), 0.5)  # (the loaded code)
print(json.dumps({"before": before, "done": done, "why": why, "after": after,
                  "mass": mass.tolist(), "hits": sum(kernel.stats.cache_hits.values()),
                  "misses": sum(kernel.stats.cache_misses.values())}))
'''


def test_a_background_compile_fills_the_cache_for_this_process(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, '-c', _BACKGROUND_PROBE], env=env,
                          capture_output=True, text=True, check=True, timeout=120)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result['before'] is False  # an empty cache
    assert result['done'] is True, result['why']
    assert result['after'] is True
    assert result['hits'] == 1 and result['misses'] == 0  # loaded, not compiled again
    assert result['mass'] == [[1.5, 0.0], [0.0, 2.0]]  # M + dt D, computed by that code


_CALL_PROBE = '''
import numpy as np
from rft_sim_ros.sand import mujoco_terms
mujoco_terms.implicit_mass(np.eye(2), np.ones(2), 0.5)  # compiled by a call, and cached
'''
_LOAD_PROBE = '''
import json
from rft_sim_ros.kernel_cache import load
from rft_sim_ros.sand import mujoco_terms
kernel = mujoco_terms.implicit_mass
load(kernel, "(float64[:, ::1], float64[::1], float64)")
print(json.dumps([sum(kernel.stats.cache_hits.values()), sum(kernel.stats.cache_misses.values())]))
'''


def test_loading_by_signature_finds_what_a_call_cached(tmp_path):
    """(The engine loads its gather kernel by signature; a warm-up fills the cache by calls.)"""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    subprocess.run([sys.executable, '-c', _CALL_PROBE], env=env, check=True, timeout=120)
    done = subprocess.run([sys.executable, '-c', _LOAD_PROBE], env=env, capture_output=True,
                          text=True, check=True, timeout=120)
    assert json.loads(done.stdout.strip().splitlines()[-1]) == [1, 0]  # a hit, no compile


_FAILING_PROBE = '''
import json
from rft_sim_ros.kernel_cache import BackgroundCompile
from rft_sim_ros.sand import mujoco_terms
print(json.dumps(BackgroundCompile([(mujoco_terms.implicit_mass, "(int64,)")]).wait()))
'''


def test_a_failed_background_compile_says_why(tmp_path):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, '-c', _FAILING_PROBE], env=env,
                          capture_output=True, text=True, check=True, timeout=120)
    ok, why = json.loads(done.stdout.strip().splitlines()[-1])
    assert ok is False
    assert 'Signature mismatch' in why, why  # the child's own error


def test_a_compiling_process_that_cannot_start_says_why(monkeypatch):
    from rft_sim_ros.kernel_cache import BackgroundCompile
    from rft_sim_ros.sand import mujoco_terms
    monkeypatch.setattr(sys, 'executable', '/nonexistent/python')  # e.g. an embedded Python
    with BackgroundCompile([(mujoco_terms.implicit_mass, '(float64[:, ::1], float64[::1], '
                                                     'float64)')]) as compiling:
        ok, why = compiling.wait()
    assert ok is False and why.startswith('no compiling process:'), why


def test_the_kernels_sources_include_the_helpers_and_constants_they_compile_in():
    names = {path.relative_to(PACKAGE).as_posix() for path in kernel_sources()}
    assert {'sand/gather.py', 'sand/implicit_solve.py', 'sand/layout.py',
            'sand/deformable_kernels.py', 'sand/deformable_codes.py', 'sand/surface_kernels.py',
            'sand/table_readers.py', 'sand/array_table.py', 'sand/surface.py', 'rft/kernel.py',
            'rft/law_rows.py', 'rft/force_law.py', 'scenes/gait_kernels.py'} <= names
    assert 'cli.py' not in names and 'sim/simulation.py' not in names
    assert not {'sand/engine.py', 'scenes/gaits.py', 'kernel_names.py', 'prebuilt.py'} & names


_KERNEL_MODULE = '''
from numba import njit

SCALE = 3.0  # a constant compiled in


@njit(cache=True)
def triple(x):
    return SCALE * x
'''


def test_kernels_compiled_from_other_sources_are_dropped(tmp_path, monkeypatch):
    """A module's cached kernels are kept while the sources fingerprint is the one they were
    compiled from, and dropped (compiled afresh) once it differs: an edit to a file the
    kernel compiles in from, which numba's own check (the kernel's file) would miss."""
    (tmp_path / 'fingerprinted_kernels.py').write_text(_KERNEL_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module('fingerprinted_kernels')
    assert module.triple(2.0) == 6.0 and is_cached(module.triple)
    assert forget_stale(vars(module), 'sources A')      # no marker yet: dropped
    assert not is_cached(module.triple)
    module.triple.recompile()                           # (compiles and caches again)
    assert is_cached(module.triple)
    assert not forget_stale(vars(module), 'sources A')  # the same sources: kept
    assert is_cached(module.triple)
    assert forget_stale(vars(module), 'sources B')      # other sources: dropped
    assert not is_cached(module.triple)


def test_unchanged_sources_are_known_by_their_stat_without_the_fingerprint(tmp_path,
                                                                          monkeypatch):
    """A marker written by the default check records each source's modification time and
    size: while they hold, the check does not compute the fingerprint; where one differs it
    does, keeps the kernels if the contents are the same (a touched file) and records the
    new times, and drops them if not."""
    import json
    from rft_sim_ros import kernel_cache
    (tmp_path / 'stat_checked_kernels.py').write_text(_KERNEL_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module('stat_checked_kernels')
    assert module.triple(2.0) == 6.0
    assert forget_stale(vars(module))                   # no marker yet: dropped
    module.triple.recompile()
    marker = Path(module.triple._cache._cache_path) / 'stat_checked_kernels.sources'
    fingerprint, _, stats = marker.read_text().partition('\n')
    assert fingerprint == sources_fingerprint()
    assert set(json.loads(stats)) == {path.relative_to(PACKAGE).as_posix()
                                      for path in kernel_sources()}

    def not_computed():
        raise AssertionError('the fingerprint was computed although no source changed')
    with monkeypatch.context() as patch:
        patch.setattr(kernel_cache, 'sources_fingerprint', not_computed)
        assert not forget_stale(vars(module)) and is_cached(module.triple)
    touched = {name: [mtime + 1, size] for name, (mtime, size) in json.loads(stats).items()}
    marker.write_text(f'{fingerprint}\n{json.dumps(touched)}')
    assert not forget_stale(vars(module)) and is_cached(module.triple)  # same contents
    assert marker.read_text() == f'{fingerprint}\n{stats}'              # times renewed
    marker.write_text(f'other sources\n{json.dumps(touched)}')
    assert forget_stale(vars(module)) and not is_cached(module.triple)


def test_every_module_with_cached_kernels_is_a_kernel_module():
    """A module of the package that defines numba kernels cached on disk is one of
    KERNEL_MODULES: `rft-sim warmup` compiles its kernels, and their cache is checked against
    the sources they are compiled from."""
    found = set()
    for path in PACKAGE.rglob('*.py'):
        if 'cache=True' in path.read_text():
            name = '.'.join((PACKAGE.name, *path.relative_to(PACKAGE).with_suffix('').parts))
            if module_kernels(name, vars(importlib.import_module(name))):
                found.add(name)
    assert found == set(KERNEL_MODULES)


def test_every_kernel_module_records_the_sources_of_its_cached_kernels():
    kernels = cached_kernels()
    for name in KERNEL_MODULES:
        kernel = next(kernel for qualified, kernel in kernels.items()
                      if qualified.rpartition('.')[0] == name)
        marker = Path(kernel._cache._cache_path) / f'{name}.sources'
        assert marker.read_text().partition("\n")[0] == sources_fingerprint(), name


_SHARE_PROBE = '''
import json, sys
from rft_sim_ros.kernel_cache import BackgroundCompile
from rft_sim_ros.sand import implicit_solve
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation
scene, parts = sys.argv[1], sys.argv[2]
share = implicit_solve.background_kernels(parts)
done, why = BackgroundCompile(share).wait()
if scene == 'elliptic':  # (no bundled scene has elliptic cones: a box by a rock)
    import mujoco
    from rft_sim_ros.sand.engine import SandEngine
    from rft_sim_ros.sand.geoms import body_plates
    model = mujoco.MjModel.from_xml_string(
        '<mujoco><option cone="elliptic"/><worldbody><body name="box"><freejoint/>'
        '<geom type="box" size="0.1 0.1 0.02"/></body>'
        '<geom type="box" pos="0.3 0 0" size="0.05 0.05 0.05"/></worldbody></mujoco>')
    plates = {'box': body_plates(model, 1, count=50)}
    assert SandEngine(model, mujoco.MjData(model), plates, zeta=3.75)._parts == parts
else:
    Simulation(load_scene(scene))
print(json.dumps({"done": done, "why": why, "stats": {
    kernel.py_func.__name__: [sum(kernel.stats.cache_hits.values()),
                              sum(kernel.stats.cache_misses.values())]
    for kernel, _ in share}}))
'''


@pytest.mark.slow  # (a whole cold compile of the implicit step in a fresh cache)
@pytest.mark.parametrize('scene, parts', [('plate_drop', 'plain'), ('hexapod', 'rows'),
                                          ('elliptic', 'cones')])
def test_the_step_loads_the_share_a_second_process_compiled(tmp_path, scene, parts):
    """The argument types `implicit_solve.background_kernels` names are those the step calls
    its kernels with: compiled by a second process first, each is loaded, none compiled
    again."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, '-c', _SHARE_PROBE, scene, parts], env=env,
                          capture_output=True, text=True, check=True, timeout=900)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result['done'], result['why']
    assert all(stats == [1, 0] for stats in result['stats'].values()), result['stats']
