"""Scenarios: the behaviour of each scene (model edits, initial state, control, metrics).

A scene YAML names its scenario: a bundled module (`scenario: plate_drop` -> module
`rft_sim_ros.scenes.scenarios.plate_drop`, its class `Scenario`), a Python file outside the
package (`scenario: my_scenario.py`, relative to the scene file; its class `Scenario`) or an
importable class (`scenario: my_package.module:MyScenario`). Each is a class derived from
`BaseScenario`. Adding a scene needs no registry.
"""
import importlib
import importlib.util
import inspect
import math
from pathlib import Path
import pkgutil
import traceback

from ..config import SceneError


class BaseScenario:
    """Hooks a scene's scenario overrides; all optional. Units SI, world frame z up.

    observe_interval: call `observe` every this many steps (1 = every step).
    """
    observe_interval = 1
    #: Whether the scene's model may make constraint rows (joint limits, equalities, contacts
    #: between its own bodies): its sand engine then loads the compiled step that solves
    #: them (`sand.engine.step_parts`) even where the model looks unable to. A bundled
    #: scene of bodies without such rows says False, so that a first run compiles less.
    constraint_rows = True

    def __init__(self, scene):
        self.scene = scene
        self.params = scene.params

    def number(self, name, minimum=None, maximum=None, positive=False):
        """Scene value `name` as a float, validated (SceneError names the problem)."""
        value = self.params.get(name)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise SceneError(f'scene {self.scene.name}: {name} must be a finite number, '
                             f'got {value!r}')
        if positive and value <= 0:
            raise SceneError(f'scene {self.scene.name}: {name} must be > 0, got {value!r}')
        if minimum is not None and value < minimum:
            raise SceneError(f'scene {self.scene.name}: {name} must be >= {minimum}, '
                             f'got {value!r}')
        if maximum is not None and value > maximum:
            raise SceneError(f'scene {self.scene.name}: {name} must be <= {maximum}, '
                             f'got {value!r}')
        return float(value)

    def choice(self, name, options):
        """Scene value `name`, one of `options` (SceneError names the problem)."""
        value = self.params.get(name)
        if value not in options:
            raise SceneError(f'scene {self.scene.name}: {name} must be one of {options}, '
                             f'got {value!r}')
        return value

    def walking_gait(self, make):
        """`make(**keywords)` with a walking scene's gait values: frequency (Hz),
        stance_fraction, step_length and step_height (m), ramp_time (s), starting at
        settle_time (s); SceneError names a bad value or gait."""
        try:
            return make(frequency_hz=self.number('frequency', positive=True),
                        stance_fraction=self.number('stance_fraction'),
                        step_length_m=self.number('step_length'),
                        step_height_m=self.number('step_height', minimum=0.0),
                        start_time_s=self.number('settle_time', minimum=0.0),
                        ramp_time_s=self.number('ramp_time', minimum=0.0))
        except ValueError as error:
            raise SceneError(f'scene {self.scene.name}: gait: {error}') from None

    def duration(self):
        """Sim time (s) the scene needs when its YAML says `duration: auto`."""
        raise SceneError(f'scene {self.scene.name}: duration is auto, but its scenario has '
                         'no duration of its own; give duration in seconds')

    def edit_model(self, spec):
        """Change the model (mujoco.MjSpec) from scene values before it is compiled."""

    def initialize(self, sim):
        """Set the initial state (sim.data) after the model is built or reset."""

    def control(self, sim):
        """Set controls before each step (sim time sim.time, s)."""

    def observe(self, sim):
        """Record what the metrics need, after a step."""

    def metrics(self, sim):
        """The scene's outputs: {name: value}, SI units in the names."""
        return {}


def load_scenario(scene):
    """Instantiate the scenario that `scene` (a SceneConfig) names (see module docstring).
    Raises SceneError, one line, where it is unknown or cannot be imported or made (a syntax
    error, an import that fails, an exception in its module or constructor: the file and
    line, and the exception's last line)."""
    reference = scene.scenario
    where = f'scene {scene.name}: scenario {reference!r}'
    if reference.endswith('.py'):
        path = Path(reference)
        if not path.is_file():
            raise SceneError(f'{where}: no such file')
        spec = importlib.util.spec_from_file_location(f'rft_scenario_{path.stem}', path)
        module = importlib.util.module_from_spec(spec)
        try:
            spec.loader.exec_module(module)
        except Exception as error:
            raise SceneError(f'{where}: cannot be imported: '
                             f'{failure_line(error, {str(path)}) or failure_line(error)}'
                             ) from None
        class_name = 'Scenario'
    else:
        module_name, _, class_name = reference.partition(':')
        if not class_name:
            module_name, class_name = f'{__name__}.{reference}', 'Scenario'
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as error:
            if error.name and module_name.startswith(error.name):
                raise SceneError(f'{where}: unknown scenario (not a bundled one, a .py file '
                                 'or an importable module:Class); bundled: '
                                 f'{", ".join(scenario_names())}') from None
            raise SceneError(f'{where}: cannot be imported: {failure_line(error)}') from None
        except Exception as error:
            raise SceneError(f'{where}: cannot be imported: {failure_line(error)}') from None
    scenario_class = getattr(module, class_name, None)
    if not (isinstance(scenario_class, type) and issubclass(scenario_class, BaseScenario)):
        raise SceneError(f'{where}: {module.__name__} has no class {class_name} derived from '
                         'rft_sim_ros.scenes.scenarios.BaseScenario')
    try:
        return scenario_class(scene)
    except SceneError:
        raise
    except Exception as error:
        line = failure_line(error, scenario_files(scenario_class)) or failure_line(error)
        raise SceneError(f'{where}: cannot be made: {line}') from None


def rows_expected(scene):
    """Whether `scene`'s (SceneConfig) scenario expects constraint rows (`BaseScenario.
    constraint_rows`): a bundled scenario says, unless the scene keeps its floor rigid
    (sand.keep_floor: its contacts make rows); any other (a file, a class of the user's) is
    taken to (it is not imported for this)."""
    reference = scene.scenario
    if (scene.keep_floor or reference.endswith('.py') or ':' in reference
            or reference not in scenario_names()):
        return True
    return importlib.import_module(f'{__name__}.{reference}').Scenario.constraint_rows


def scenario_files(scenario_class):
    """The source files (absolute paths) of the methods a scenario class and its bases other
    than BaseScenario define: where an exception raised in its code is told by its
    traceback (`failure_line`)."""
    return {function.__code__.co_filename for klass in scenario_class.__mro__
            if klass not in (BaseScenario, object) for function in vars(klass).values()
            if inspect.isfunction(function)}


def failure_line(error, files=None):
    """'FILE:LINE: Type: message' of exception `error`: the deepest line of its traceback in
    one of `files` (None: the deepest line of all; a SyntaxError: the line it names), and its
    last line as Python prints it; None where no frame of its traceback is in `files`."""
    last = traceback.format_exception_only(type(error), error)[-1].strip()
    if isinstance(error, SyntaxError) and error.filename and (
            files is None or error.filename in files):
        return f'{error.filename}:{error.lineno}: {last}'
    frames = [frame for frame in traceback.extract_tb(error.__traceback__)
              if files is None or frame.filename in files]
    if not frames:
        return None if files is not None else last
    return f'{frames[-1].filename}:{frames[-1].lineno}: {last}'


def scenario_names():
    """Names of the bundled scenario modules (what a scene's `scenario:` may say), sorted."""
    return sorted(module.name for module in pkgutil.iter_modules(__path__))
