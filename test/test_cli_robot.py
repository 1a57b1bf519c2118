"""`rft-sim run ROBOT_FILE`: a bare robot file runs in sand in a scene made for it, with the
robot options (--sand-bodies, --base, --package-path, --xacro-arg); bad input: one line, exit 2.
"""
import json
from pathlib import Path

import pytest

from rft_sim_ros.cli import main
from rft_sim_ros.scenes.config import SceneError, load_scene
from rft_sim_ros.scenes.schema import BY_PATH

#: Plates per sand body of a robot file's scene: the schema's default, as a scene file's.
ROBOT_PLATES = BY_PATH['rft.plates_per_body'].default

PACKAGE = Path(__file__).parent / 'robots' / 'sandbot_description'
XACRO = PACKAGE / 'urdf' / 'sandbot.urdf.xacro'
FEET = 'fl_foot,fr_foot,rl_foot,rr_foot'
ROBOT_OPTIONS = ['--package-path', f'sandbot_description={PACKAGE}', '--sand-bodies', FEET]


def test_robot_file_scene_defaults():
    scene = load_scene(XACRO, {'rft.sand_bodies': ['fl_foot']})
    assert scene.name == 'sandbot' and scene.scenario == 'external'
    assert scene.model_path == XACRO.resolve()
    assert (scene.timestep, scene.zeta) == (0.001, 3.75)
    assert scene.duration == BY_PATH['duration'].default
    assert scene.plates_per_body == ROBOT_PLATES and scene.robot['base'] is None  # (as the
    assert scene.spawn == 'auto'  # URDF says; spawn auto: rest under the external scenario)


def test_robot_file_runs_in_sand_with_the_plates_asked(tmp_path):
    out = tmp_path / 'run'
    code = main(['run', str(XACRO), *ROBOT_OPTIONS, '--xacro-arg', 'hip_effort=20',
                 '--set', 'sand.surface_height=-0.25', '--duration', '0.2', '--out', str(out),
                 '--quiet'])
    assert code == 0
    summary = json.loads((out / 'summary.json').read_text())
    assert sum(summary['plates_per_body'][b] for b in summary['sand_bodies']) == 4 * ROBOT_PLATES
    assert summary['stable'] and summary['plates_active_mean'] > 0
    assert (out / 'bag').is_dir()
    # what reading the description changed is in the summary (and, unquiet, on the terminal)
    assert any('dropped 1 visual mesh' in notice for notice in summary['notices'])


@pytest.mark.parametrize('arguments, message', [
    (['missing.urdf'], 'robot file missing.urdf not found'),
    ([str(XACRO), '--sand-bodies', FEET], "cannot find package 'sandbot_description'"),
    ([str(XACRO), '--package-path', 'sandbot_description', '--sand-bodies', FEET],
     '--package-path expects NAME=VALUE'),
    ([str(XACRO), '--package-path', f'sandbot_description={PACKAGE}/nowhere',
      '--sand-bodies', FEET], 'no such folder'),
    ([str(XACRO), *ROBOT_OPTIONS, '--set', 'robot.base=welded'], 'robot.base: must be one of'),
    ([str(XACRO), '--package-path', f'sandbot_description={PACKAGE}',
      '--sand-bodies', 'fl_foot,hoof'], "sand body 'hoof' matches no body"),
])
def test_bad_robot_input_is_one_line_and_exit_2(arguments, message, capsys, monkeypatch,
                                                tmp_path):
    monkeypatch.delenv('ROS_PACKAGE_PATH', raising=False)
    assert main(['run', *arguments, '--duration', '0.01', '--no-bag', '--quiet',
                 '--out', str(tmp_path / 'out')]) == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert error.startswith('rft-sim: error: ') and message in error


def test_fixed_base_option_welds_the_robot():
    scene = load_scene(XACRO, {'robot.base': 'fixed', 'rft.sand_bodies': ['fl_foot']})
    assert scene.robot['base'] == 'fixed'
    with pytest.raises(SceneError, match='robot.xacro_args: must be a mapping'):
        load_scene(XACRO, {'robot.xacro_args': 'hip_effort=3', 'rft.sand_bodies': ['fl_foot']})
