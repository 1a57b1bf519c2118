"""The rft_sim node's parameters: which may change at runtime and which values are refused."""
import math

import pytest

from rft_sim_ros.ros import parameters
from rft_sim_ros.ros.parameters import parameter_problem
from rft_sim_ros.ros.robot_source import load_node_scene, scene_overrides
from rft_sim_ros.scenes.config import SceneError, load_scene


@pytest.mark.parametrize('value, words', [
    (-1, '> 0'), (0.0, '> 0'), (math.nan, 'finite'), (math.inf, 'finite'),
    (100.5, '<= 100'), ('abc', 'number'), (True, 'number'), ([1.0], 'number')])
def test_bad_zeta_is_refused_with_the_reason(value, words):
    problem = parameter_problem('zeta', value)
    assert problem and words in problem and 'zeta' in problem


@pytest.mark.parametrize('value', [0.1, 1, 3.75, 100.0])
def test_good_zeta_is_accepted(value):
    assert parameter_problem('zeta', value) is None


@pytest.mark.parametrize('value, words', [(-0.5, '>= 0'), (math.nan, 'finite'),
                                          (math.inf, 'finite'), ('fast', 'number'),
                                          (False, 'number')])
def test_bad_real_time_factor_is_refused(value, words):
    problem = parameter_problem('real_time_factor', value)
    assert problem and words in problem


@pytest.mark.parametrize('value', [0, 0.0, 0.25, 1, 50.0])
def test_good_real_time_factor_is_accepted(value):
    assert parameter_problem('real_time_factor', value) is None


def test_paused_must_be_a_bool():
    assert parameter_problem('paused', True) is None
    assert parameter_problem('paused', False) is None
    assert 'true or false' in parameter_problem('paused', 1)


@pytest.mark.parametrize('name', ['scene', 'scene_overrides', 'publish_rate', 'joint_names',
                                  'plates'])
def test_static_parameters_are_read_only(name):
    assert not parameters.SPECS[name].dynamic
    assert 'read-only' in parameter_problem(name, 'anything')


def test_dynamic_parameters_are_exactly_zeta_rate_paused_and_gains():
    assert {s.name for s in parameters.PARAMETERS if s.dynamic} == {
        'zeta', 'real_time_factor', 'paused', 'joint_gains'}


def test_unknown_parameter_is_named():
    assert "'speed'" in parameter_problem('speed', 1.0)


@pytest.mark.parametrize('bad', [0, -10.0, math.nan, math.inf, 'fast', True])
def test_publish_rate_must_be_positive(bad):
    with pytest.raises(ValueError, match='publish_rate'):
        parameters.publish_rate(bad)
    assert parameters.publish_rate(50) == 50.0


def test_scene_overrides_parse_like_the_cli():
    assert scene_overrides(['gait=none', 'payload=1.5', 'rft.plates_per_body=80']) == {
        'gait': 'none', 'payload': 1.5, 'rft.plates_per_body': 80}
    assert scene_overrides(None) == {}
    with pytest.raises(SceneError, match='key=value'):
        scene_overrides(['gait'])
    with pytest.raises(SceneError, match='list'):
        scene_overrides('gait=none')


@pytest.mark.parametrize('name, kept', [('arm_controller', 'arm_controller'),
                                        ('/left/joint_trajectory_controller',
                                         'left/joint_trajectory_controller')])
def test_a_trajectory_controller_is_a_ros_name(name, kept):
    assert parameters.trajectory_controller(name) == kept


@pytest.mark.parametrize('bad', ['', 'arm controller', '2arm', 'arm//x', 'arm/', '~/x', 3])
def test_a_trajectory_controller_that_is_no_ros_name_is_refused(bad):
    with pytest.raises(ValueError, match='trajectory_controller must be a ROS name'):
        parameters.trajectory_controller(bad)


#: rcl's errors (Jazzy) for ROS arguments it cannot read, as rclpy raises them.
RULE_ERROR = ("Failed to parse ROS arguments: Couldn't parse parameter override rule: "
              "'-p sand_bodies:=*_foot'. Error: Unknown YAML event, at "
              "/opt/ros2_jazzy/src/rcl/rcl_yaml_param_parser/src/parse.c:965, at "
              "/opt/ros2_jazzy/src/rcl/rcl/src/rcl/arguments.c:352")
REMAP_ERROR = ("Failed to parse ROS arguments: Couldn't parse remap rule: '-r foo'. Error: "
               "Expected lexeme type (19) not found, search ended at index 3, at "
               "/opt/ros2_jazzy/src/rcl/rcl/src/rcl/lexer_lookahead.c:239, at "
               "/opt/ros2_jazzy/src/rcl/rcl/src/rcl/arguments.c:380")


def test_a_parameter_rule_that_is_no_yaml_is_named_with_how_to_quote_it():
    problem = parameters.arguments_problem(RULE_ERROR)
    assert "the parameter rule '-p sand_bodies:=*_foot' is not valid YAML" in problem
    assert '''-p "sand_bodies:='*_foot'"''' in problem
    quoted_item = '''-p "scene_overrides:=[sand.surface.type=grid, 'sand.surface.size=[2,2]']"'''
    assert quoted_item in problem
    assert '\n' not in problem and '.c:' not in problem


def test_other_unreadable_arguments_keep_rcls_reason_without_its_sources():
    assert parameters.arguments_problem(REMAP_ERROR) == (
        "Failed to parse ROS arguments: Couldn't parse remap rule: '-r foo'. Error: Expected "
        'lexeme type (19) not found, search ended at index 3')


def test_scene_overrides_are_named_so_in_errors(tmp_path):
    """A bad value or assignment in the node's scene_overrides is named `scene_overrides KEY`,
    not with the CLI's `--set` (which keeps its own wording)."""
    bad = scene_overrides(['sand.deformable.enabled=true', 'sand.deformable.cell=-1'])
    with pytest.raises(SceneError, match=r'plate_drop.yaml: scene_overrides sand.deformable.cell: '
                                         r'must be > 0, got -1'):
        load_node_scene('plate_drop', '', '', '', bad, tmp_path)
    with pytest.raises(SceneError, match="scene_overrides expects key=value, got 'gait'"):
        scene_overrides(['gait'])
    with pytest.raises(SceneError, match="scene_overrides params: 'factor:0.3' was read as a key"):
        scene_overrides(['params={x: 1, factor:0.3}'])
    with pytest.raises(SceneError, match='plate_drop.yaml: --set sand.deformable.cell: must be'):
        load_scene('plate_drop', {'sand.deformable.cell': -1})
