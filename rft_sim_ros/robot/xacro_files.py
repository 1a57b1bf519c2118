"""xacro expansion without ROS, through the `xacro` package (ROS's own xacro, published on
PyPI by its maintainers: same macro language and error messages as `ros2 run xacro xacro`).

`$(find pkg)` resolves through a PackageResolver (user's package paths, the ament index,
ROS_PACKAGE_PATH) instead of xacro's ament-only lookup; `$(arg k)` takes `args`.
"""
import contextlib
import threading
import xml.dom.minidom

import xacro
from xacro import substitution_args

from .packages import PackageNotFound

# xacro keeps module-level state (file stack, the find hook): one expansion at a time.
_LOCK = threading.Lock()


class XacroError(ValueError):
    """xacro could not expand a file; the message names the file and the problem."""


@contextlib.contextmanager
def _find_through(resolver):
    original = substitution_args._eval_find
    substitution_args._eval_find = lambda name: str(resolver.find(name))
    try:
        yield
    finally:
        substitution_args._eval_find = original


def expand_xacro(path, resolver, args=None):
    """The XML text of xacro file `path` expanded with `args` ({name: value})."""
    mappings = {str(k): str(v) for k, v in (args or {}).items()}
    with _LOCK, _find_through(resolver):
        try:
            document = xacro.process_file(str(path), mappings=mappings)
        except PackageNotFound as error:
            raise XacroError(f'{path}: {error}') from None
        except (xacro.XacroException, xml.parsers.expat.ExpatError, OSError,
                NameError, KeyError, TypeError, ValueError, SyntaxError) as error:
            raise XacroError(f'{path}: xacro: {_message(error)}') from None
    return document.toprettyxml(indent='  ')


def _message(error):
    """One line for xacro's `error`; an undefined $(arg NAME), raised as it is or wrapped in
    a XacroException (xacro:if, xacro:unless), says how to give it."""
    missing = error if isinstance(error, substitution_args.ArgException) else getattr(
        error, 'exc', None)
    if isinstance(missing, substitution_args.ArgException):
        name = str(missing).strip()
        return (f'undefined xacro argument {name}: give it with --xacro-arg {name}=VALUE '
                '(robot.xacro_args in a scene)')
    text = str(error).strip() or type(error).__name__
    return ' '.join(text.split())
