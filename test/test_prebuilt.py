"""Kernels built ahead of time (`prebuild`, `prebuilt`): a run on them gives the results
numba's kernels give, to the bit, and imports no numba; a table in another order still
raises; arguments of other types than a kernel was built for run numba's kernel; an
extension that no longer fits this process (its sources, numba, numpy, Python, the CPU), or
one switched off, is not used, and `prebuilt.state` says why."""
import json
import os
import shutil
import subprocess
import sys
import sysconfig

import numpy as np
import pytest

from rft_sim_ros import prebuilt
from rft_sim_ros.kernel_names import CALLED_KERNELS, FOOT_PATH, GATHERS, PREBUILT
from rft_sim_ros.prebuild import build
from rft_sim_ros.sand import gather
from rft_sim_ros.sand.array_table import ArrayTable
from rft_sim_ros.sand.surface import SURFACE_KINDS
from rft_sim_ros.sand.surface_codes import FLAT, GRID, KINDS, SLOPE
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.scenes.gait_kernels import foot_path
from rft_sim_ros.sim.simulation import Simulation

_PLANE = GATHERS['plane']


def _c_compiler():
    """The C compiler numba's ahead-of-time compiler calls (Python's build configuration),
    or None where it is not installed."""
    command = (sysconfig.get_config_var('CC') or 'cc').split()[0]
    return shutil.which(command)


@pytest.fixture(scope='module')
def built(tmp_path_factory):
    """A folder with an extension of every kernel `rft-sim warmup` builds
    (`kernel_names.PREBUILT`)."""
    if _c_compiler() is None:
        pytest.skip('no C compiler: numba.pycc cannot build the prebuilt kernels here')
    folder = tmp_path_factory.mktemp('prebuilt')
    build(PREBUILT, folder)
    return folder


@pytest.fixture
def use(monkeypatch):
    """use(folder): runs in this test load the prebuilt kernels of `folder` (the test run
    has them off: conftest)."""
    def use(folder):
        monkeypatch.setenv(prebuilt.SWITCH, '1')
        monkeypatch.setattr(prebuilt, 'FOLDER', folder)
        prebuilt.load.cache_clear()
    yield use
    prebuilt.load.cache_clear()


def _drop(steps=3000):
    """The plate drop after `steps` steps: final qpos and qvel, its plates' forces (K, 3),
    and its engine."""
    sim = Simulation(load_scene('plate_drop'))
    sim.step(steps)
    _, forces, _ = sim.engine.active_plates()
    return np.concatenate([sim.data.qpos, sim.data.qvel]), forces, sim.engine


def test_a_run_on_prebuilt_kernels_gives_numbas_results_to_the_bit(built, use):
    jit, jit_forces, engine = _drop()
    assert not prebuilt.has(engine._gathering)
    assert engine.kernels == f'prebuilt kernels: off ({prebuilt.SWITCH}=0)'
    use(built)
    assert prebuilt.state() == 'prebuilt kernels: in use'
    ahead, ahead_forces, engine = _drop()
    assert all(prebuilt.has(kernel) for kernel, _ in PREBUILT)
    assert engine.kernels == 'prebuilt kernels: in use'
    assert engine._gather is not gather.gather_plane  # (the extension's function is called)
    assert np.array_equal(ahead, jit) and np.array_equal(ahead_forces, jit_forces)
    assert jit[2] < 0.0  # (the plate sank into the sand: the kernels had work to do)
    assert len(jit_forces) > 50 and jit_forces[:, 2].sum() > 0.0


@pytest.mark.parametrize('scene, overrides', [
    ('plate_drop', {}), ('hexapod', {}), ('quadruped', {}),
    ('plate_drop', {'rft.low_velocity.method': 'ema'}),
    ('plate_drop', {'sand.deformable.enabled': True})])
def test_a_run_on_prebuilt_kernels_imports_no_numba(built, scene, overrides):
    run = ('import sys\n'
           'from pathlib import Path\n'
           'from rft_sim_ros import prebuilt\n'
           f'prebuilt.FOLDER = Path({str(built)!r})\n'
           'from rft_sim_ros.scenes.config import load_scene\n'
           'from rft_sim_ros.sim.runner import run_scene\n'
           f'summary = run_scene(load_scene({scene!r}, {overrides!r}), duration=0.05, '
           'progress=False)\n'
           "print(summary['stable'], 'numba' in sys.modules, summary['machine']['kernels'])\n")
    done = subprocess.run([sys.executable, '-c', run], capture_output=True, text=True,
                          env=dict(os.environ, **{prebuilt.SWITCH: '1'}), check=True)
    assert done.stdout.split('\n')[-2] == 'True False prebuilt kernels: in use', done.stderr


def test_the_gaits_call_the_prebuilt_kernels_with_what_they_were_built_for(built):
    """The gaits the gait node makes (`make_gait`) import no numba: the standing gait's
    leg inverse is given columns of the neutral feet, which it hands on C-ordered."""
    run = ('import sys\n'
           'from pathlib import Path\n'
           'from rft_sim_ros import prebuilt\n'
           f'prebuilt.FOLDER = Path({str(built)!r})\n'
           'from rft_sim_ros.scenes.gaits import make_gait\n'
           "for name in ('none', 'tripod'):\n"
           '    make_gait(name).targets(1.3)\n'
           "print('numba' in sys.modules)\n")
    done = subprocess.run([sys.executable, '-c', run], capture_output=True, text=True,
                          env=dict(os.environ, **{prebuilt.SWITCH: '1'}), check=True)
    assert done.stdout.split('\n')[-2] == 'False', done.stderr


def test_a_prebuilt_kernel_given_other_types_runs_numbas(built, use):
    use(built)
    path = prebuilt.kernel(FOOT_PATH)
    assert path is not foot_path  # (the extension's, checked)
    phases = np.linspace(0.0, 0.99, 7)
    expected = foot_path(phases, 0.5, 0.05, 0.02)
    assert all(np.array_equal(a, b) for a, b in zip(path(phases, 0.5, 0.05, 0.02), expected))
    # each of these, unboxed as the extension's float64 C-contiguous array, would read other
    # memory: numba's kernel takes them, as a call from Python always has
    read_only = phases.copy()
    read_only.flags.writeable = False
    for other in (phases.astype(np.float32), np.repeat(phases, 2)[::2], read_only,
                  phases.view(np.recarray)):
        assert all(np.allclose(a, b) for a, b in zip(path(other, 0.5, 0.05, 0.02), expected))
    with pytest.raises(TypeError):  # (the wrong number of arguments)
        path(phases, 0.5, 0.05)


@pytest.mark.parametrize('other, why', [
    (lambda p: (p.astype(np.float32), 0.5), 'argument 1 is a 1-D float32 array'),
    (lambda p: (np.repeat(p, 2)[::2], 0.5), 'argument 1 is a 1-D float64 array (not C-contiguous)'),
    (lambda p: (p.view(np.recarray), 0.5), 'argument 1 is a 1-D float64 array (a recarray)'),
    (lambda p: (p, np.float32(0.5)), 'argument 2 is a numpy float32'),
    (lambda p: (p, 1), 'argument 2 is a Python int')])
def test_a_prebuilt_kernel_given_other_types_says_so(built, use, other, why):
    """Such a call is said, with the argument that did not match: by the state line of a
    simulation made before it (`Simulation.kernels`: a run's summary, /diagnostics) and by
    its run, once a start for each argument; a simulation made after says nothing of it."""
    use(built)
    path = prebuilt.kernel(FOOT_PATH)
    before = Simulation(load_scene('plate_drop'))
    phases = np.linspace(0.0, 0.99, 7)
    given = (*other(phases), 0.05, 0.02)
    assert before.kernels == 'prebuilt kernels: in use' and before.run_warnings() == []
    path(*given)
    said = f'{why}, built for {"float64[::1]" if why.startswith("argument 1") else "float64"}'
    assert before.kernels == f"prebuilt kernels: in use; numba's for foot_path ({said})"
    assert before.run_warnings() == [
        f'the prebuilt kernel foot_path was called with other types than it was built for '
        f"({said}): numba's kernel runs those calls, with the same results, after it "
        'compiles or loads']
    assert before.run_warnings() == []
    after = Simulation(load_scene('plate_drop'))
    assert after.kernels == 'prebuilt kernels: in use' and after.run_warnings() == []
    path(*given)  # (again: said by the run made after it, once)
    assert len(after.run_warnings()) == 1 and before.run_warnings() == []
    path(phases.astype(np.int64), 0.5, 0.05, 0.02)  # (another argument: said too)
    other_said = 'argument 1 is a 1-D int64 array, built for float64[::1]'
    first, *fallbacks = after.kernels.split('; ')  # (in the order the process first saw them)
    assert first == 'prebuilt kernels: in use' and sorted(fallbacks) == sorted(
        f"numba's for foot_path ({reason})" for reason in (said, other_said))
    assert [other_said in line for line in after.run_warnings()] == [True]
    after.reset()  # (a new start: said again)
    assert after.run_warnings() == []
    path(*given)
    assert len(after.run_warnings()) == 1
    mark = prebuilt.fallback_calls()
    path(*given)
    assert prebuilt.fallbacks_since(mark) == [(FOOT_PATH, said)]


def test_each_kind_of_surface_names_its_gather_kernel():
    """The engine finds its gather by its surface's kind code's name (`surface_codes.KINDS`)."""
    assert (KINDS[FLAT], KINDS[SLOPE], KINDS[GRID]) == ('plane', 'slope', 'grid')
    assert tuple(GATHERS) == KINDS
    for code, kind in enumerate(KINDS):  # (each gather bound to its kind's code)
        assert prebuilt.dispatcher(GATHERS[kind]).py_func.__globals__['KIND'] == code
    assert all(KINDS[SURFACE_KINDS[kind]] == kind for kind in KINDS)  # (a scene's type)


def test_a_fallback_says_what_of_an_array_did_not_match():
    read_only, wanted = np.zeros((2, 3)), "Array(float64, 2, 'C', readonly=True)"
    assert prebuilt._described(read_only, wanted) == 'a 2-D float64 array (writeable)'
    read_only.flags.writeable = False
    assert prebuilt._described(read_only[:, ::2], 'float64[:, ::1]') == (
        'a 2-D float64 array (not C-contiguous, read-only)')
    assert prebuilt._described(np.float64(1.0), 'int64') == 'a numpy float64'


def test_the_kernels_called_from_python_are_built_for_the_types_runs_call_them_with():
    from numba.core import sigutils
    from rft_sim_ros.sim.runner import run_scene
    from rft_sim_ros.sand.surface import HeightGrid
    for scene, overrides in (('hexapod', {}), ('quadruped', {}),  # (prebuilt: off in tests)
                             ('plate_drop', {'rft.low_velocity.method': 'ema'})):
        run_scene(load_scene(scene, overrides), duration=0.01, progress=False, plots=False)
    HeightGrid(np.zeros((4, 5)), (0.4, 0.3)).height(np.zeros(3), np.ones(3))
    for name, signature in CALLED_KERNELS:
        arguments, _ = sigutils.normalize_signature(signature)
        assert tuple(arguments) in prebuilt.dispatcher(name).overloads, name


def test_a_table_in_another_order_raises_in_a_prebuilt_kernel(built, use):
    use(built)
    gathering = prebuilt.kernel(_PLANE)
    assert gathering is not gather.gather_plane
    swapped = ArrayTable(np.zeros(3, dtype=np.int8), np.zeros((2, 2)))
    with pytest.raises(TypeError, match='another dtype or rank'):
        gathering(swapped.table)


def _copy(built, tmp_path, **changes):
    """A copy of the built folder whose record has `changes`."""
    folder = tmp_path / 'copy'
    shutil.copytree(built, folder)
    record_file = folder / prebuilt.toolchain_key(prebuilt.toolchain()) / prebuilt.RECORD
    record = json.loads(record_file.read_text())
    record.update(changes)
    record_file.write_text(json.dumps(record))
    return folder


@pytest.mark.parametrize('name', ['numba', 'numpy', 'python', 'cpu', 'cpu_features',
                                  'numba_cpu_name', 'numba_cpu_features', 'numba_enable_avx'])
def test_an_extension_built_with_another_toolchain_is_not_used(built, use, monkeypatch, name):
    use(built)
    assert prebuilt.has(_PLANE)
    other = dict(prebuilt.toolchain(), **{name: 'other'})
    monkeypatch.setattr(prebuilt, 'toolchain', lambda: other)
    prebuilt.load.cache_clear()
    assert not prebuilt.has(_PLANE)
    assert prebuilt.state() == ('prebuilt kernels: not built for this numba, numpy, Python '
                                'and CPU (`rft-sim warmup` builds them)')


def test_an_extension_of_other_sources_is_not_used(built, use, tmp_path):
    use(_copy(built, tmp_path, stats={'sand/gather.py': [1, 2]}, fingerprint='0' * 64))
    assert not prebuilt.has(_PLANE)
    assert prebuilt.state() == ('prebuilt kernels: built from other sources (they changed '
                                'since): `rft-sim warmup` builds them again')


def test_a_record_without_the_sources_times_checks_their_fingerprint(built, use, tmp_path):
    use(_copy(built, tmp_path, stats=None, fingerprint='0' * 64))
    assert not prebuilt.has(_PLANE)


def test_sources_touched_but_the_same_keep_the_extension(built, use, tmp_path):
    use(_copy(built, tmp_path, stats={'sand/gather.py': [1, 2]}))
    assert prebuilt.has(_PLANE)


@pytest.mark.parametrize('setting', ['DISABLE_JIT', 'BOUNDSCHECK'])
def test_numbas_debugging_settings_turn_it_off(built, use, monkeypatch, setting):
    use(built)
    monkeypatch.setenv(f'NUMBA_{setting}', '1')
    prebuilt.load.cache_clear()
    assert prebuilt.state() == f'prebuilt kernels: off (NUMBA_{setting} is set)'
    monkeypatch.setenv(f'NUMBA_{setting}', '0')
    prebuilt.load.cache_clear()
    assert prebuilt.state() == 'prebuilt kernels: in use'


def test_numbas_code_settings_make_another_toolchain(monkeypatch):
    for setting in prebuilt.CODE_SETTINGS:
        monkeypatch.delenv(setting, raising=False)
    here = prebuilt.toolchain()
    for setting in prebuilt.CODE_SETTINGS:
        for value in ('', '0'):  # (set but empty is not unset: empty NUMBA_CPU_NAME is generic)
            with monkeypatch.context() as patched:
                patched.setenv(setting, value)
                other = prebuilt.toolchain()
                assert other != here and other['cpu_features'] == here['cpu_features']


def test_a_kernel_now_called_with_other_types_is_not_taken_from_the_extension(built, use,
                                                                             tmp_path):
    use(_copy(built, tmp_path, kernels=dict(PREBUILT, **{FOOT_PATH: '(float32[::1],)'})))
    assert not prebuilt.has(FOOT_PATH) and prebuilt.has(_PLANE)


def test_no_extension_is_built_under_the_settings_a_run_refuses(monkeypatch, tmp_path):
    monkeypatch.setenv('NUMBA_BOUNDSCHECK', '1')
    with pytest.raises(RuntimeError, match='not built: NUMBA_BOUNDSCHECK is set'):
        build(PREBUILT[:1], tmp_path)
    assert not any(tmp_path.iterdir())


def test_a_numba_configuration_file_turns_it_off(built, use, monkeypatch, tmp_path):
    use(built)
    monkeypatch.chdir(tmp_path)
    (tmp_path / prebuilt.CONFIG_FILE).write_text('boundscheck: 1\n')
    prebuilt.load.cache_clear()
    assert prebuilt.state() == ("prebuilt kernels: off (numba's .numba_config.yaml in the "
                                'working folder sets its options)')


def test_no_extension_and_the_switch_say_so(use, tmp_path, monkeypatch):
    use(tmp_path)
    assert prebuilt.state() == ('prebuilt kernels: not built for this numba, numpy, Python '
                                'and CPU (`rft-sim warmup` builds them)')
    monkeypatch.setenv(prebuilt.SWITCH, '0')
    prebuilt.load.cache_clear()
    assert prebuilt.state() == f'prebuilt kernels: off ({prebuilt.SWITCH}=0)'


def test_the_extension_holds_each_kernel_it_was_given(built, use):
    use(built)
    functions, _ = prebuilt.load()
    assert sorted(functions) == sorted(name for name, _ in PREBUILT)


def test_a_build_that_fails_says_why_and_the_warmup_goes_on(monkeypatch):
    from rft_sim_ros import warmup
    failed = subprocess.CompletedProcess([], 1, stdout='', stderr=(
        'Traceback (most recent call last):\n  ...\n'
        "distutils.errors.CompileError: command 'gcc' failed: No such file or directory\n"))
    monkeypatch.setattr(warmup.subprocess, 'run', lambda *args, **kwargs: failed)
    assert warmup.prebuild() == ("prebuilt kernels: not built (distutils.errors.CompileError: "
                                 "command 'gcc' failed: No such file or directory)")
    monkeypatch.undo()
    monkeypatch.setattr(warmup.sys, 'executable', '/nonexistent/python')
    assert warmup.prebuild().startswith('prebuilt kernels: not built (no building process: ')


def test_the_building_process_says_why_it_failed_on_one_line(monkeypatch, capsys):
    from rft_sim_ros import prebuild

    def no_compiler(kernels):
        raise RuntimeError('Attempted to compile AOT function without the compiler present.'
                           ' If using conda try:\n\n#> conda install gcc_linux-64')
    monkeypatch.setattr(prebuild, 'build', no_compiler)
    assert prebuild.main() == 1
    assert capsys.readouterr().err == (
        'RuntimeError: Attempted to compile AOT function without the compiler present. If '
        'using conda try: #> conda install gcc_linux-64\n')


def test_an_engine_says_which_of_its_kernels_are_not_prebuilt(built, use, tmp_path):
    use(_copy(built, tmp_path, kernels=dict(
        (name, signature) for name, signature in PREBUILT if name != GATHERS['slope'])))
    slope = Simulation(load_scene('plate_drop', {'sand.surface.type': 'slope'})).engine
    assert not prebuilt.has(GATHERS['slope'])  # (not in this extension)
    assert slope.kernels == ('prebuilt kernels: not built for gather_slope (`rft-sim warmup` '
                             'builds them)')
    paper = Simulation(load_scene('plate_drop', {'rft.coupling': 'paper',
                                                 'rft.low_velocity.method': 'ema'})).engine
    assert paper.kernels == 'numpy (rft.coupling: paper), no compiled kernels'
