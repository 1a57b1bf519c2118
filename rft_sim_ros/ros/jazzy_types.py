"""The ROS 2 Jazzy message types a bag records, without loading rosbags' whole Jazzy store.

rosbags builds a class for each of the 162 types of its Jazzy store when the store is first
loaded: 0.17 s, most of a bag's start (0.27 s) on a 2-core AMD EPYC VM, where a bag needs
some 30 of them. `typestore_for` gives a rosbags typestore holding only the types asked for
and those they nest, with rosbags' own Jazzy definitions: taken from its store the first
time they are asked for (`rft-sim warmup` asks for every type a bag may record) and kept in
the user's cache (one file per rosbags version, `cache_file`), so that later runs register
those few only (0.03 s). A cache file that cannot be read, or
that lacks a type asked for, is made again from the store; one that cannot be written leaves
the runs to take the store each time.
"""
import functools
import json
import os
import tempfile
from importlib.metadata import version
from pathlib import Path

from rosbags.interfaces import Nodetype

from ..resources import user_cache_dir

#: Bump when the cache file's layout changes.
_FORMAT = 1


def cache_file():
    """$XDG_CACHE_HOME/rft_sim_ros/ros_types/jazzy-<rosbags version>-<format>.json
    (default ~/.cache/...: `resources.user_cache_dir`)."""
    return user_cache_dir('ros_types') / f'jazzy-{version("rosbags")}-{_FORMAT}.json'



@functools.lru_cache(maxsize=None)
def typestore_for(type_names):
    """A rosbags typestore with the Jazzy definitions of `type_names` (a frozenset of
    'pkg/msg/Name') and of every type they nest, as rosbags' Jazzy store has them."""
    from rosbags.typesys import Stores, get_typestore
    path = cache_file()
    cached = _read(path)
    definitions = _closure(type_names, cached)
    if definitions is None:
        from .factory import jazzy_typestore
        definitions = _closure(type_names, jazzy_typestore().fielddefs)
        if definitions is None:
            raise ValueError(f'not every one of {sorted(type_names)} is a ROS 2 Jazzy type of '
                             f'rosbags {version("rosbags")}')
        _write(path, {**cached, **definitions})
    typestore = get_typestore(Stores.EMPTY)
    typestore.register(definitions)
    return typestore


def _closure(type_names, fielddefs):
    """{name: definition} of `type_names` and the types they nest, from `fielddefs`; None
    where one of them is not there."""
    found, pending = {}, list(type_names)
    while pending:
        name = pending.pop()
        if name in found:
            continue
        if name not in fielddefs:
            return None
        found[name] = fielddefs[name]
        for _, description in found[name][1]:
            while description[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE):
                description = description[1][0]
            if description[0] == Nodetype.NAME:
                pending.append(description[1])
    return found


def _read(path):
    """The cache file's {name: definition} (rosbags' form: tuples, `Nodetype`s); {} where it
    is missing or cannot be read, or holds anything but definitions."""
    try:
        stored = json.loads(path.read_text())
        return {name: ([tuple(constant) for constant in constants],
                       [(field, _description(description)) for field, description in fields])
                for name, (constants, fields) in stored.items()}
    except (OSError, ValueError, TypeError, LookupError, AttributeError):
        return {}


def _description(stored):
    """A field's type description from its JSON form: (Nodetype, payload), nested; ValueError
    for any other form."""
    kind, payload = Nodetype(stored[0]), stored[1]
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return kind, (_description(payload[0]), _whole(payload[1]))
    if kind == Nodetype.NAME and isinstance(payload, str):
        return kind, payload
    if kind == Nodetype.BASE and isinstance(payload, list) and len(payload) == 2 \
            and isinstance(payload[0], str):
        return kind, (payload[0], _whole(payload[1]))
    raise ValueError(f'not a type description: {stored!r}')


def _whole(value):
    """`value` where it is a whole number (a length or bound), else ValueError."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f'not a length: {value!r}')
    return value


def _write(path, definitions):
    """Write the cache file (atomically: a run reading it meanwhile sees the old one or the
    new); nothing where it cannot be written."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, partial = tempfile.mkstemp(dir=path.parent, prefix=f'{path.name}.')
    except OSError:
        return
    try:
        with os.fdopen(handle, 'w') as out:
            json.dump(definitions, out)
        os.replace(partial, path)
    except OSError:
        Path(partial).unlink(missing_ok=True)
