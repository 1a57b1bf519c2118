"""Which robot and scene the `rft_sim` node loads, from its parameters (ROS-free).

Parameters `scene` (a bundled scene, scene YAML or robot file), `model` (a robot file:
MJCF, URDF, xacro) and `robot_description` (the robot's XML, as robot_state_publisher
publishes it). Rules:
- `model` and `robot_description` exclude each other;
- with a `scene`, either replaces the scene's model (scene key `model`);
- without one, the robot runs in the scene `rft-sim run ROBOT_FILE` would give it;
- none of the three set (`parameters.needs_topic`): the description comes from the
  /robot_description topic (`topics.ROBOT_DESCRIPTION`, std_msgs/String, transient local),
  then as `robot_description`.
`sand_bodies` ('A,B*' or 'auto') sets rft.sand_bodies; `scene_overrides` reads the parameter of
that name. A description string is stored as a file
(`description_file`, content-addressed) so the scene can name it; package:// and file://
URIs and absolute paths in it resolve as usual, relative paths have no folder to resolve
against but the file's.
"""
import hashlib
from pathlib import Path

from rft_sim_ros.robot.urdf import parse_xml
from rft_sim_ros.ros.parameters import SCENE_OVERRIDES
from rft_sim_ros.scenes.config import (SceneError, anchor_paths, load_scene, parse_assignment,
                                       robot_overrides)

def description_file(text, folder):
    """Path of a file in `folder` holding description `text` (.urdf or .xml by its root
    element; named by its content's hash, so the same text gives the same file)."""
    kind = parse_xml(text, 'robot_description').tag
    suffix = '.urdf' if kind == 'robot' else '.xml'
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f'robot_description-{hashlib.sha1(text.encode()).hexdigest()[:12]}{suffix}'
    if not path.is_file():
        path.write_text(text)
    return path


def load_node_scene(scene, model, robot_description, sand_bodies, overrides, folder):
    """The SceneConfig the parameters ask for (see module docstring); `overrides` are the
    node's scene_overrides (errors name them so), `folder` holds description files. Raises
    SceneError or ValueError (urdf.UrdfError for a malformed string)."""
    if model and robot_description:
        raise ValueError('set one of the parameters model and robot_description, not both')
    robot = str(description_file(robot_description, folder)) if robot_description else model
    overrides = {**overrides, **robot_overrides(sand_bodies or None)}
    if scene and robot:
        overrides = {**overrides, 'model': str(Path(robot).expanduser().resolve())}
    return load_scene(scene or robot, overrides, SCENE_OVERRIDES)


def scene_overrides(assignments):
    """{key: value} from 'key=value' strings (values read as YAML; relative files from the
    working directory, `anchor_paths`); raises SceneError."""
    if isinstance(assignments, str):
        raise SceneError(f"scene_overrides must be a list of 'key=value' strings, "
                         f'got the string {assignments!r}')
    overrides = dict(parse_assignment(str(text), SCENE_OVERRIDES) for text in assignments or ())
    return anchor_paths(overrides, Path.cwd())  # files it names: from the working directory
