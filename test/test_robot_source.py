"""Which scene the rft_sim node loads from scene / model / robot_description / sand_bodies
(rft_sim_ros.ros.robot_source, ROS-free)."""
from pathlib import Path

import pytest

from rft_sim_ros.robot.xacro_files import expand_xacro
from rft_sim_ros.robot.packages import PackageResolver
from rft_sim_ros.ros.parameters import needs_topic
from rft_sim_ros.ros.robot_source import description_file, load_node_scene
from rft_sim_ros.scenes.config import SceneError

ROBOTS = Path(__file__).parent / 'robots'
PACKAGE = ROBOTS / 'sandbot_description'
XACRO = PACKAGE / 'urdf' / 'sandbot.urdf.xacro'
SERVO_RIG = Path(__file__).parent / 'scenes' / 'servo_rig.yaml'


def test_topic_only_when_nothing_names_the_robot():
    assert needs_topic('', '', '')
    assert not needs_topic('hexapod', '', '')
    assert not needs_topic('', 'robot.urdf', '')
    assert not needs_topic('', '', '<robot name="r"/>')


def test_description_string_becomes_one_file_per_content(tmp_path):
    text = expand_xacro(XACRO, PackageResolver({'sandbot_description': PACKAGE}))
    first = description_file(text, tmp_path)
    assert first.suffix == '.urdf' and first.read_text() == text
    assert description_file(text, tmp_path) == first
    assert description_file('<mujoco/>', tmp_path).suffix == '.xml'
    with pytest.raises(ValueError, match='robot_description: malformed XML at line 1'):
        description_file('<robot>', tmp_path)


def test_robot_description_string_runs_in_the_robot_scene(tmp_path, monkeypatch):
    monkeypatch.setenv('ROS_PACKAGE_PATH', str(ROBOTS))
    text = expand_xacro(XACRO, PackageResolver())
    scene = load_node_scene('', '', text, 'fl_foot,rr_foot', {}, tmp_path)
    assert scene.scenario == 'external' and scene.sand_bodies == ('fl_foot', 'rr_foot')
    assert scene.model_path.parent == tmp_path


def test_model_replaces_the_scene_model_and_alone_makes_the_robot_scene(tmp_path):
    scene = load_node_scene(str(SERVO_RIG), str(XACRO), '', '', {}, tmp_path)
    assert scene.model_path == XACRO.resolve() and scene.name == 'servo_rig'
    scene = load_node_scene('', str(XACRO), '', 'fl_foot', {'zeta': 2.0}, tmp_path)
    assert scene.name == 'sandbot' and scene.zeta == 2.0


def test_model_and_robot_description_exclude_each_other(tmp_path):
    with pytest.raises(ValueError, match='one of the parameters model and robot_description'):
        load_node_scene('', str(XACRO), '<robot name="r"/>', '', {}, tmp_path)
    with pytest.raises(SceneError, match='not found'):
        load_node_scene('', 'missing.urdf', '', '', {}, tmp_path)
