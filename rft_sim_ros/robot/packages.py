"""Where ROS packages live: `$(find pkg)`, `package://pkg/...` and `file://...` to paths.

Resolution order for a package name: the `--package-path NAME=DIR` map given by the user,
the ament index (when ROS 2 is sourced: `ament_index_python` importable), rft_sim_ros
itself (its share folder, found as `resources` does), then `ROS_PACKAGE_PATH` (folders that are a package, named by their package.xml's <name> or
their folder name, or that hold packages one level down). The package's own share folder
is returned (for an installed package) or its source folder.
"""
import os
import re
from pathlib import Path
from urllib.parse import unquote, urlparse

from .. import resources


class PackageNotFound(LookupError):
    """A package name cannot be resolved; the message says where it looked."""


def parse_package_paths(items):
    """{name: Path} from 'NAME=DIR' strings (or a mapping); raises ValueError on bad ones."""
    if isinstance(items, dict):
        return {str(name): Path(folder).expanduser() for name, folder in items.items()}
    paths = {}
    for item in items or ():
        name, sep, folder = str(item).partition('=')
        if not sep or not name.strip() or not folder.strip():
            raise ValueError(f'--package-path expects NAME=DIR, got {item!r}')
        paths[name.strip()] = Path(folder.strip()).expanduser()
    return paths


def _package_name(folder):
    manifest = folder / 'package.xml'
    if manifest.is_file():
        match = re.search(r'<name>\s*([^<\s]+)\s*</name>', manifest.read_text(errors='replace'))
        if match:
            return match.group(1)
    return folder.name


class PackageResolver:
    """Finds package folders (see module docstring). `package_paths`: {name: folder}."""

    def __init__(self, package_paths=None):
        self.package_paths = parse_package_paths(package_paths)
        for name, folder in self.package_paths.items():
            if not folder.is_dir():
                raise ValueError(f'--package-path {name}={folder}: no such folder')

    def find(self, name):
        """The folder of package `name`; raises PackageNotFound."""
        if name in self.package_paths:
            return self.package_paths[name].resolve()
        try:
            from ament_index_python.packages import (PackageNotFoundError,
                                                     get_package_share_directory)
        except ImportError:
            pass
        else:
            try:
                return Path(get_package_share_directory(name))
            except PackageNotFoundError:
                pass
        if name == resources.PACKAGE:  # this package itself, installed or not
            return resources.share_dir()
        for root in filter(None, os.environ.get('ROS_PACKAGE_PATH', '').split(os.pathsep)):
            root = Path(root)
            for folder in (root, *(sorted(root.iterdir()) if root.is_dir() else ())):
                if folder.is_dir() and _package_name(folder) == name:
                    return folder.resolve()
        raise PackageNotFound(
            f'cannot find package {name!r}: give --package-path {name}=DIR, set '
            'ROS_PACKAGE_PATH, or source the ROS workspace that installs it')

    def resolve_uri(self, uri, base_dir):
        """Path of a mesh or include reference: package://pkg/rel, file:///abs, an absolute
        path, or a path relative to `base_dir` (the description's folder; None for a string
        description: then relative paths resolve against the working directory)."""
        if uri.startswith('package://'):
            name, _, rest = uri[len('package://'):].partition('/')
            return self.find(name) / unquote(rest)
        if uri.startswith('file://'):
            return Path(unquote(urlparse(uri).path))
        path = Path(uri).expanduser()
        if not path.is_absolute() and base_dir is not None:
            path = Path(base_dir) / path
        return path
