"""The node's start-up (`rft_sim_ros.ros.startup`, ROS-free): the simulation is built in a
worker thread while the executor thread keeps answering; what start-up says meanwhile."""
import dataclasses
import os
import subprocess
import sys
import threading
import time

import pytest

from rft_sim_ros.ros.startup import SimStartup, StartFailed, compile_in_child
from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.sim.simulation import Simulation


def _until(predicate, timeout=30.0):
    """Wait (wall s) for `predicate()` to be true; returns it."""
    deadline = time.monotonic() + timeout
    while not predicate() and time.monotonic() < deadline:
        time.sleep(0.01)
    return predicate()


class _Clock:
    """A wall clock the test sets (s)."""

    def __init__(self, now=100.0):
        self.now = now

    def __call__(self):
        return self.now


def _held_build(value):
    """(build function of a scene returning `value` once `release` is set, release Event)."""
    release = threading.Event()

    def build(scene):
        assert release.wait(30)
        return value
    return build, release


def _read(scene='the scene'):
    return lambda: scene


def _compiles(scene):
    return 'compiling kernels, first run only'


def test_nothing_is_handed_over_until_built_then_once():
    build, release = _held_build('the simulation')
    startup = SimStartup(_read(), build, notice=_compiles)
    assert startup.building and startup.result() is None
    release.set()
    assert startup.wait(30)
    assert startup.result() == 'the simulation'
    assert startup.result() is None  # handed over once


def test_progress_counts_wall_seconds_and_says_what_it_does():
    clock = _Clock(100.0)
    build, release = _held_build(1)
    scene_read = threading.Event()

    def held_read():
        assert scene_read.wait(30)
        return 'the scene'
    compiling = SimStartup(held_read, build, notice=_compiles, clock=clock)
    cached = SimStartup(held_read, build, clock=clock)
    clock.now = 101.6
    assert compiling.progress() == 'reading the scene, 2 s so far' and compiling.scene is None
    scene_read.set()
    assert _until(lambda: compiling.scene and cached.scene)
    assert compiling.compiling and compiling.notice == 'compiling kernels, first run only'
    assert not cached.compiling and cached.notice is None
    clock.now = 112.4
    assert compiling.progress() == 'compiling kernels, 12 s so far'
    assert cached.progress() == 'building the simulation, 12 s so far'
    assert compiling.elapsed() == pytest.approx(12.4)
    release.set()


def test_a_bad_scene_fails_the_start_with_its_reason():
    def build(scene):
        raise SceneError('scene x: model does not compile: no such mesh')
    startup = SimStartup(_read(), build, errors=(SceneError, ValueError))
    assert startup.wait(30)
    with pytest.raises(StartFailed, match='no such mesh'):
        startup.result()


def test_a_scene_that_does_not_read_fails_the_start_with_its_reason():
    def read():
        raise SceneError('unknown scene no_such_scene')
    startup = SimStartup(read, lambda scene: pytest.fail('built'), errors=(ValueError,))
    assert startup.wait(30) and startup.scene is None
    with pytest.raises(StartFailed, match='unknown scene no_such_scene'):
        startup.result()


def test_a_defect_in_the_build_propagates_as_it_is():
    def build(scene):
        raise ZeroDivisionError('a bug')
    startup = SimStartup(_read(), build, errors=(SceneError,))
    assert startup.wait(30)
    with pytest.raises(ZeroDivisionError, match='a bug'):
        startup.result()


def test_services_meanwhile_take_pause_and_refuse_the_rest_with_the_reason():
    clock = _Clock(0.0)
    build, release = _held_build(1)
    startup = SimStartup(_read(), build, notice=_compiles, clock=clock)
    assert _until(lambda: startup.scene)
    clock.now = 7.0
    paused = startup.pause_answer(True)
    assert paused.success and paused.message == ('the simulation will start paused once built '
                                                 '(compiling kernels, 7 s so far)')
    assert startup.pause_answer(False).message.startswith('the simulation will start running')
    for service in ('reset', 'step', 'reset_terrain'):
        refused = startup.refusal(service)
        assert not refused.success
        assert refused.message.startswith(f'{service}: the simulation is not built yet '
                                          '(compiling kernels, 7 s so far); try again')
    release.set()


def test_diagnostics_meanwhile_say_it_starts_and_with_what():
    clock = _Clock(0.0)
    build, release = _held_build(1)
    startup = SimStartup(_read(), build, notice=_compiles, clock=clock)
    assert _until(lambda: startup.scene)
    clock.now = 3.25
    fields = startup.diagnostic_fields('quadruped', 5.0, False)
    assert (fields.level, fields.name, fields.hardware_id) == (0, 'rft_sim: simulation',
                                                               'quadruped')
    assert fields.message == 'starting: compiling kernels, 3 s so far'
    values = dict(fields.values)
    assert values == {'starting_s': '3.2', 'compiling_kernels': 'true',
                      'zeta_n_per_cm3': '5.0', 'paused': 'false'}
    assert float(values['zeta_n_per_cm3']) == 5.0
    unread = dict(startup.diagnostic_fields('quadruped', None, True).values)
    assert 'zeta_n_per_cm3' not in unread and unread['paused'] == 'true'  # (the scene's)
    release.set()


def test_a_real_simulation_is_built_in_the_worker_thread():
    scene = load_scene('plate_drop')
    startup = SimStartup(lambda: scene, Simulation)
    assert startup.wait(900)
    sim = startup.result()
    assert isinstance(sim, Simulation) and sim.time == 0.0
    sim.step(2)
    assert sim.time == pytest.approx(2 * scene.timestep)


def test_the_kernels_compile_first_in_a_child_process_where_they_must():
    calls = []

    def warm(scene):
        calls.append(f'warm {scene}')
        return 'no compiling process: test'

    def build(scene):
        calls.append(f'build {scene}')
        return 'sim'
    cached = SimStartup(_read('s'), build, notice=lambda scene: None, warm=warm)
    assert cached.wait(30) and cached.result() == 'sim' and calls == ['build s']
    calls.clear()
    cold = SimStartup(_read('s'), build, notice=_compiles, warm=warm)
    assert cold.wait(30) and cold.result() == 'sim' and calls == ['warm s', 'build s']
    assert cold.warm_problem == 'no compiling process: test'  # the build went on anyway


def test_the_compiling_process_builds_the_scene_or_says_why_not(tmp_path):
    assert compile_in_child(load_scene('plate_drop'), timeout=600) is None
    broken = tmp_path / 'broken.xml'
    broken.write_text('<mujoco><worldbody><geom type="no_such_type"/></worldbody></mujoco>')
    scene = dataclasses.replace(load_scene('plate_drop'), model_path=broken)
    problem = compile_in_child(scene, timeout=600)
    assert 'SceneError: scene plate_drop: ' in problem and 'no_such_type' in problem


_RESPONSIVE_PROBE = '''
import json, time
from rft_sim_ros.ros.startup import SimStartup, compile_in_child
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation, compile_notice
scene = load_scene("plate_drop")
compiling = compile_notice(scene) is not None
startup = SimStartup(lambda: scene, Simulation, notice=compile_notice, warm=compile_in_child)
gaps, last = [], time.monotonic()
while startup.building:          # the executor thread's turns, 10 ms apart when idle
    time.sleep(0.01)
    now = time.monotonic()
    gaps.append(now - last)
    last = now
startup.result()
print(json.dumps({"compiling": compiling, "build_s": startup.elapsed(), "turns": len(gaps),
                  "longest_gap_s": max(gaps), "warm_problem": startup.warm_problem}))
'''


@pytest.mark.slow
def test_the_executor_thread_keeps_its_turn_while_the_kernels_compile(tmp_path):
    """A cold cache (an empty NUMBA_CACHE_DIR): while the kernels compile (in the child
    process, then the simulation is built in the worker thread), the main thread still gets
    its turns, never 2 s apart (the node's promise: a parameter answered within 2 s). On the
    busy two-core VM (load ~12): longest gap 0.9 s over a 394 s cold build, the worker only
    waiting for the child then (the OS's scheduling); a compile in this process held the GIL
    for garbage collections of up to 6.5 s (14 gaps over 0.5 s in 793 s)."""
    import json
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    done = subprocess.run([sys.executable, '-c', _RESPONSIVE_PROBE], env=env,
                          capture_output=True, text=True, check=True, timeout=900)
    probe = json.loads(done.stdout.strip().splitlines()[-1])
    assert probe['compiling'] and probe['build_s'] > 1.0 and probe['warm_problem'] is None
    assert probe['longest_gap_s'] < 2.0, probe
