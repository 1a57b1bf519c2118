"""Locate the package's shared files (config/, models/, launch/), and the user's cache of
what the package makes once and keeps (`user_cache_dir`).

One mechanism for every install: setup.py installs these folders under share/rft_sim_ros;
a ROS workspace finds that through the ament index, a pip install through sys.prefix, and a
source checkout (editable install, tests) has them next to the package.
"""
import os
import sys
from pathlib import Path

PACKAGE = 'rft_sim_ros'


def _candidates():
    yield Path(__file__).resolve().parent.parent  # source checkout
    try:
        from ament_index_python.packages import (PackageNotFoundError,
                                                 get_package_share_directory)
        try:
            yield Path(get_package_share_directory(PACKAGE))
        except PackageNotFoundError:
            pass
    except ImportError:
        pass
    yield Path(sys.prefix) / 'share' / PACKAGE


def share_dir():
    """The folder that holds config/ and models/ (first match of the install kinds above)."""
    for candidate in _candidates():
        if (candidate / 'config').is_dir() and (candidate / 'models').is_dir():
            return candidate
    raise FileNotFoundError(
        f'cannot find the {PACKAGE} share folder (config/, models/); is the package installed?')


def user_cache_dir(name):
    """$XDG_CACHE_HOME/rft_sim_ros/`name` (default ~/.cache/rft_sim_ros/`name`): where the
    package keeps what it makes once for this user (plates, a bag's message types)."""
    base = os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return Path(base) / PACKAGE / name


def config_dir():
    """Folder of the bundled scene YAML files."""
    return share_dir() / 'config'


def models_dir():
    """Folder of the bundled MJCF models."""
    return share_dir() / 'models'
