"""The scene schema: its reference doc, errors that name file, line and key, effective values,
scenarios outside the package, and the metrics every scene reports."""
import json
from pathlib import Path

import pytest

from rft_sim_ros import cli, resources
from rft_sim_ros.scenes import schema
from rft_sim_ros.scenes.config import (SceneError, bundled_scenes, load_scene, parse_assignment,
                                       robot_file_name)
from rft_sim_ros.sim.runner import run_scene
from rft_sim_ros.sim.simulation import Simulation

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / 'docs' / 'scene-reference.md'

MINIMAL = """\
name: mini
model: plate.xml
rft:
  sand_bodies: [plate]
  plates_per_body: 50
legs:
  plate: [plate]
"""


def write(tmp_path, text, name='scene.yaml'):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_reference_doc_lists_every_key_as_the_schema_says():
    document = REFERENCE.read_text()
    assert schema.with_reference_table(document) == document, (
        'docs/scene-reference.md is out of step with the schema: run '
        'python -m rft_sim_ros.scenes.schema --write docs/scene-reference.md')
    for key in schema.KEYS:
        assert f'| `{key.path}` |' in document


def test_every_bundled_scene_passes_the_schema():
    for name, path in bundled_scenes().items():
        scene = load_scene(path)
        assert set(scene.values) <= set(schema.BY_PATH), name


def test_a_robot_file_names_its_scene_by_its_stem_or_a_generic_stems_folder(tmp_path):
    assert robot_file_name('/w/anymal_c/anymal_c.xml') == 'anymal_c'
    assert robot_file_name('desc/urdf/my_robot.urdf.xacro') == 'my_robot'
    assert robot_file_name('/m/unitree_go2/scene.xml') == 'unitree_go2'
    assert robot_file_name('scene.xml') == Path.cwd().name  # (the folder it is in)
    menagerie = tmp_path / 'plate_robot'
    menagerie.mkdir()
    (menagerie / 'scene.xml').write_text(
        (resources.models_dir() / 'plate.xml').read_text())
    assert load_scene(str(menagerie / 'scene.xml')).name == 'plate_robot'


def test_defaults_fill_a_minimal_scene(tmp_path):
    scene = load_scene(write(tmp_path, MINIMAL))
    assert scene.scenario == 'external'
    assert scene.timestep == 0.001 and scene.zeta == 3.75 and scene.surface_height == 0.0
    assert scene.low_velocity == {'method': 'implicit', 'rest_speed': 1e-5, 'ema_alpha': 0.1}
    assert scene.values['rft.plates_per_body'] == 50


def test_a_renamed_key_still_loads_under_its_old_name_with_a_notice(tmp_path):
    """rft.bodies (the old name of rft.sand_bodies, schema.RENAMED_KEYS) in a file or an
    override loads as the new key; the run's notices say where and the new name; a scene
    that gives both names is refused."""
    old = write(tmp_path, MINIMAL.replace('sand_bodies:', 'bodies:'))
    scene = load_scene(old)
    assert scene.sand_bodies == ('plate',) and 'rft.bodies' not in scene.values
    assert scene.notices == (f'{old}:4: rft.bodies is deprecated, now called rft.sand_bodies '
                             '(the old name is accepted for this release)',)
    assert Simulation(scene).notices[0] == scene.notices[0]
    overridden = load_scene(write(tmp_path, MINIMAL, 'new.yaml'), {'rft.bodies': ['plate']})
    assert overridden.sand_bodies == ('plate',)
    assert overridden.notices == ('--set rft.bodies is deprecated, now called rft.sand_bodies '
                                  '(the old name is accepted for this release)',)
    with pytest.raises(SceneError, match=r'scene.yaml:4: rft.bodies is the old name of '
                                         r'rft.sand_bodies, which the scene also gives'):
        load_scene(write(tmp_path, MINIMAL.replace('rft:\n', 'rft:\n  bodies: [plate]\n')))


@pytest.mark.parametrize('edit, line, key, words', [
    (('  plates_per_body: 50', '  plates_per_bdy: 50'), 5, 'rft.plates_per_bdy',
     'did you mean rft.plates_per_body'),
    (('  plates_per_body: 50', '  plates_per_body: -2'), 5, 'rft.plates_per_body',
     'positive integer'),
    (('name: mini', 'name: mini\ntimestep: fast'), 2, 'timestep', 'finite number'),
    (('name: mini', 'name: mini\nzeta: 0'), 2, 'zeta', '> 0'),
    (('  plate: [plate]', '  plate: [plat]'), 7, 'legs.plate', "'plat' is not a sand body"),
    (('  sand_bodies: [plate]', '  sand_bodies: [plate, "*foot*"]'), 4, 'rft.sand_bodies',
     "sand body '*foot*' matches no body"),
    (('model: plate.xml', 'model: plate.xml\nrobot:\n  keyframe: home'), 4, 'robot.keyframe',
     "keyframe 'home' is not in the model"),
    (('name: mini', 'name: mini\nservos: {"*": {kp: -1}}'), 2, 'servos', '*.kp: must be'),
    (('name: mini', 'name: mini\nrobot: {spawn: "drop:x"}'), 2, 'robot.spawn',
     'must be auto, model, rest or drop:HEIGHT'),
    (('name: mini', 'name: mini\nrft_bodies: 1'), 2, 'rft_bodies', 'unknown key'),
    (('model: plate.xml\n', ''), None, 'model', 'missing (required)'),  # no line to name
    (('name: mini', 'name: mini\nsand:\n  surface_height: [1]'), 3, 'sand.surface_height',
     'finite number'),
    # a key of another kind of surface or map than the scene's would have no effect
    (('name: mini', 'name: mini\nsand:\n  surface:\n    angle_deg: 10'), 4,
     'sand.surface.angle_deg', 'applies to sand.surface.type slope, and this scene has '
     'sand.surface.type plane: drop the key or change that'),
    (('name: mini', 'name: mini\nsand:\n  surface: {type: slope, size: [1, 1]}'), 3,
     'sand.surface.size', 'applies to sand.surface.type grid, and this scene has '
     'sand.surface.type slope'),
    (('name: mini', 'name: mini\nsand:\n  zeta_map:\n    regions: [{x: [0, 1], y: [0, 1], '
      'factor: 0.5}]\n    file: loose.npy'), 5, 'sand.zeta_map.file',
     'applies to a map from sand.zeta_map.file, and this scene has a map of '
     'sand.zeta_map.regions'),
    (('name: mini', 'name: mini\nsand:\n  zeta_map: {file: loose.npy, cell: 0.02}'), 3,
     'sand.zeta_map.cell', 'applies to a map of sand.zeta_map.regions, and this scene has a '
     'map from sand.zeta_map.file'),
    (('name: mini', 'name: mini\nsand:\n  zeta_map:\n    regions: [{x: [0, 1], y: [0, 1], '
      'factor: 0.5, z: 3}]'), 4, 'sand.zeta_map.regions', 'region 0: unknown key z (a region '
     'is {x: [low, high], y: [low, high], factor: f})'),
])
def test_errors_name_file_line_and_key(tmp_path, edit, line, key, words):
    """Schema errors come from load_scene, those that need the model (body names, keyframes)
    from the Simulation: both name the file, the line and the key."""
    path = write(tmp_path, MINIMAL.replace(*edit))
    with pytest.raises(SceneError) as error:
        Simulation(load_scene(path))
    where = f'{path}:{line}' if line else f'{path}'
    assert str(error.value).startswith(f'{where}: {key}: ')
    assert words in str(error.value)


def test_syntax_errors_and_overrides_say_where(tmp_path):
    with pytest.raises(SceneError, match=r"scene.yaml:4: not valid YAML: (did not find )?expected ','"):
        load_scene(write(tmp_path, 'name: x\nmodel: plate.xml\nrft: {a: b\n  c d]\n'))
    with pytest.raises(SceneError, match=r'scene.yaml: --set timestep: must be > 0'):
        load_scene(write(tmp_path, MINIMAL), {'timestep': -1})


def test_a_colon_without_a_space_is_named_not_read_as_a_key(tmp_path):
    """YAML reads `{factor:0.3}` as the key 'factor:0.3' without a value; the error says so,
    in a scene file and in --set, instead of a validator's 'got {...}' later."""
    with pytest.raises(SceneError, match=r"--set sand.zeta_map.regions: 'factor:0.3' was read "
                       r'as a key without a value: YAML needs a space after the colon '
                       r'\(factor: 0.3\)'):
        parse_assignment('sand.zeta_map.regions=[{x: [0, 1], y: [0, 1], factor:0.3}]')
    path = write(tmp_path, MINIMAL + 'sand: {zeta_map: {regions: [{x: [0, 1], y: [0, 1], '
                 'factor:0.3}]}}\n')
    with pytest.raises(SceneError, match=f"{path}: 'factor:0.3' was read as a key"):
        load_scene(path)
    assert parse_assignment('sand.zeta_map.regions=[{x: [0, 1], y: [0, 1], factor: 0.3}]')[1] \
        == [{'x': [0, 1], 'y': [0, 1], 'factor': 0.3}]


def test_a_map_key_without_regions_or_file_is_not_called_the_other_kinds(tmp_path):
    """With neither regions nor a file the map's kind is unknown: the key is not refused as
    the other kind's; the missing map is said when the map is built."""
    scene = load_scene(write(tmp_path, MINIMAL), {'sand.zeta_map.cell': 0.02})
    with pytest.raises(SceneError, match='sand.zeta_map needs regions, or file and size'):
        Simulation(scene)


def test_an_unknown_override_names_the_closest_setting(tmp_path):
    with pytest.raises(SceneError, match=r"unknown setting 'sand.deformable.enabeld' \(did you "
                       r'mean sand.deformable.enabled\?\): a setting is a scene key'):
        load_scene(write(tmp_path, MINIMAL), {'sand.deformable.enabeld': True})
    with pytest.raises(SceneError, match=r"'payloda' \(did you mean payload\?\): .* or one of "
                       r"the scenario's values \(cycles, drop_height, "):
        load_scene('hexapod', {'payloda': 1.0})


def test_numbers_in_exponent_form_are_numbers_everywhere(tmp_path):
    """YAML 1.1 (PyYAML) reads 1e-3 and 5e-2 as text; scene files, --set values and lists
    in them read them as numbers, as YAML 1.2 and users do; text stays text."""
    path = write(tmp_path, MINIMAL + 'timestep: 5e-4\nsand: {surface_height: -2E-2, '
                 'zeta_map: {regions: [{x: [-1e0, 1], y: [0, 2e-1], factor: 5e-1}]}}\n')
    scene = load_scene(path, dict([parse_assignment('duration=2e-1')]))
    assert scene.timestep == 5e-4 and scene.surface_height == -0.02 and scene.duration == 0.2
    assert scene.values['sand.zeta_map.regions'] == [{'x': [-1.0, 1], 'y': [0, 0.2],
                                                       'factor': 0.5}]
    assert parse_assignment('sand.surface.center=[1e-1,0]') == ('sand.surface.center', [0.1, 0])
    assert parse_assignment('rft.sand_bodies=[e5, 1e]') == ('rft.sand_bodies', ['e5', '1e'])
    assert parse_assignment('x=1_000')[1] == 1000 and parse_assignment('x=.5')[1] == 0.5


def test_scenes_command_prints_effective_values_and_set_keys(capsys):
    assert cli.main(['scenes', 'plate_drop', '--set', 'timestep=0.002']) == 0
    out = capsys.readouterr().out
    assert '  timestep = 0.002\n' in out
    assert '  rft.low_velocity.method = "implicit"\n' in out
    assert '  rft.plate_density_per_mm2 = null  (default)' in out
    assert '  drop_height = 0.1' in out  # a scene value (params)
    assert '  sand.zeta_map.regions  (unset: sand.zeta_map is off)\n' in out  # every key
    listed = {line.split()[0] for line in out.splitlines() if line.startswith('  ')}
    assert {key.path for key in schema.KEYS if not key.section} - {'params'} <= listed
    assert cli.main(['scenes', 'plate_drop', '--set', 'timestep=-1']) == 2


def test_a_scenario_outside_the_package_runs_and_reports(tmp_path):
    scene = load_scene(ROOT / 'docs' / 'examples' / 'hold_still.yaml')
    summary = run_scene(scene, None, progress=False)
    generic = summary['generic_metrics']
    # the plate falls from its model pose into the sand: the scenario's own metric and the
    # generic displacement see the same fall
    assert summary['metrics']['base_sink_m'] == pytest.approx(
        -generic['base_displacement_xyz_m'][2], rel=1e-9)
    assert summary['metrics']['base_sink_m'] > 0.05


def test_a_scenario_named_module_colon_class(tmp_path, monkeypatch):
    (tmp_path / 'my_scenarios.py').write_text(
        'from rft_sim_ros.scenes.scenarios import BaseScenario\n'
        'class Sinking(BaseScenario):\n'
        '    def metrics(self, sim):\n'
        '        return {"steps": sim.steps}\n'
        'class NotAScenario:\n    pass\n')
    monkeypatch.syspath_prepend(str(tmp_path))
    path = write(tmp_path, MINIMAL + 'scenario: my_scenarios:Sinking\nduration: 0.01\n')
    assert run_scene(load_scene(path), None, progress=False)['metrics'] == {'steps': 10}
    path = write(tmp_path, MINIMAL + 'scenario: my_scenarios:NotAScenario\n')
    with pytest.raises(SceneError, match='no class NotAScenario derived from'):
        run_scene(load_scene(path), None, progress=False)
    path = write(tmp_path, MINIMAL + 'scenario: missing.py\n')
    with pytest.raises(SceneError, match='no such file'):
        run_scene(load_scene(path), None, progress=False)


def test_generic_metrics_of_a_plate_at_rest_in_sand():
    """A plate dropped on sand: the generic metrics agree with the scenario's own depth
    and, at rest, the sand carries its weight."""
    scene = load_scene('plate_drop', {'duration': 1.5, 'rft.plates_per_body': 100})
    summary = run_scene(scene, None, progress=False)
    generic, own = summary['generic_metrics'], summary['metrics']
    assert generic['stable'] is True
    # the plate's lowest plate is its bottom face: the same depth the scenario measures
    assert generic['max_sinkage_m_plate'] == pytest.approx(own['max_sinkage_m'], rel=1e-3)
    assert 0 < generic['mean_stance_sinkage_m_plate'] <= generic['max_sinkage_m_plate']
    weight = 1.0 * 9.81
    assert generic['peak_force_z_N_plate'] > 2 * weight  # the impact
    assert generic['final_speed_mps'] < 1e-3
    assert generic['base_displacement_m'] == pytest.approx(
        abs(generic['base_displacement_xyz_m'][2]))
    assert generic['base_mean_speed_mps'] * 1.5 >= generic['base_displacement_m'] - 1e-9
    json.dumps(summary['generic_metrics'])
