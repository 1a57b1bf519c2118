"""The pip path of a colcon build: requirements.txt lists every PyPI package that setup.py
says the package and its tests need, so `pip install -r requirements.txt` installs all of
them into the Python that ROS uses."""
import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _name(requirement):
    """The normalised project name of a requirement line ('ruamel.yaml.clib>=0.2' ->
    'ruamel-yaml-clib')."""
    return re.sub(r'[-_.]+', '-', re.match(r'\s*([A-Za-z0-9._-]+)', requirement)[1]).lower()


def _setup_keyword(name):
    """The literal value of keyword `name` of setup() in setup.py."""
    tree = ast.parse((ROOT / 'setup.py').read_text())
    call = next(node for node in ast.walk(tree) if isinstance(node, ast.Call)
                and getattr(node.func, 'id', None) == 'setup')
    return ast.literal_eval(next(k.value for k in call.keywords if k.arg == name))


def _requirements():
    lines = (ROOT / 'requirements.txt').read_text().splitlines()
    return [line.strip() for line in lines if line.strip() and not line.startswith('#')]


def test_requirements_cover_the_run_time_and_the_tests():
    listed = {_name(line) for line in _requirements()}
    needed = {_name(r) for r in _setup_keyword('install_requires')
              + _setup_keyword('extras_require')['test']}
    assert needed - listed == set()
    assert listed - needed == set()  # nothing there that setup.py does not justify


def test_the_pytest_of_the_ros_path_loads_launch_testing():
    """Jazzy's launch_testing pytest plugin does not load with pytest 9."""
    pytest_line = next(line for line in _requirements() if _name(line) == 'pytest')
    assert '<9' in pytest_line.replace(' ', '')
