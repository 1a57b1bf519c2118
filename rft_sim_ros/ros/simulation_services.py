"""The simulator-neutral services of ROS 2's `simulation_interfaces` package, answered from a
`SimRuntime`'s pause / step / reset.

ROS-free: `SimulationServices` decides every answer as plain numbers and text; the node
fills the package's messages from them (and starts without these services, saying so once,
where the package is not installed). The constants are those of simulation_interfaces 1.x
(its jazzy branch; checked against 1.5.1 on a real Jazzy) and 2.x
(github.com/ros-simulation/simulation_interfaces: msg/SimulatorFeatures.msg,
msg/SimulationState.msg, msg/Result.msg, srv/ResetSimulation.srv, srv/SetSimulationState.srv,
action/SimulateSteps.action).

What this simulator supports, as GetSimulatorFeatures says it:

* ResetSimulation (SIMULATION_RESET, SIMULATION_RESET_STATE): the scene back to its initial
  state (robot, sand, commands), as ~/reset. Sim time keeps running forward (a ROS clock never
  goes back), so SCOPE_TIME alone is not supported (SIMULATION_RESET_TIME is not listed);
  SCOPE_DEFAULT and SCOPE_ALL reset everything else and say so. Nothing is ever spawned, so
  SCOPE_SPAWNED has nothing to remove: alone it changes nothing (and says so).
* StepSimulation (STEP_SIMULATION_SINGLE, STEP_SIMULATION_MULTIPLE) and the SimulateSteps
  action (STEP_SIMULATION_ACTION, feedback after each step): while paused, `steps`
  iterations of the simulation loop, each one publish period of sim time followed by its
  state publication, as ~/step. The action runs its steps at once (as the service does): a
  cancel request is refused.
* GetSimulationState / SetSimulationState (SIMULATION_STATE_GETTING, _SETTING, _PAUSE):
  PLAYING, PAUSED, and STOPPED: paused at the scene's initial state (started paused, or reset
  while paused, by any reset service), until stepped, played or set to PAUSED, as the
  package's SimulationState says ("equivalent to pausing and resetting").
Not supported: spawning, entities, named poses, worlds, quitting.
"""
from dataclasses import dataclass

# simulation_interfaces/msg/SimulatorFeatures
SIMULATION_RESET, SIMULATION_RESET_TIME, SIMULATION_RESET_STATE = 20, 21, 22
SIMULATION_STATE_GETTING, SIMULATION_STATE_SETTING, SIMULATION_STATE_PAUSE = 24, 25, 26
STEP_SIMULATION_SINGLE, STEP_SIMULATION_MULTIPLE, STEP_SIMULATION_ACTION = 31, 32, 33
# simulation_interfaces/msg/SimulationState
STATE_STOPPED, STATE_PLAYING, STATE_PAUSED, STATE_QUITTING = 0, 1, 2, 3
# simulation_interfaces/msg/Result
RESULT_FEATURE_UNSUPPORTED, RESULT_OK, RESULT_NOT_FOUND = 0, 1, 2
RESULT_INCORRECT_STATE, RESULT_OPERATION_FAILED = 3, 4
# simulation_interfaces/srv/ResetSimulation scopes (bits)
SCOPE_DEFAULT, SCOPE_TIME, SCOPE_STATE, SCOPE_SPAWNED, SCOPE_ALL = 0, 1, 2, 4, 255
# simulation_interfaces/srv/SetSimulationState results
ALREADY_IN_TARGET_STATE, STATE_TRANSITION_ERROR, INCORRECT_TRANSITION = 101, 102, 103

#: What GetSimulatorFeatures lists (module docstring).
FEATURES = (SIMULATION_RESET, SIMULATION_RESET_STATE, SIMULATION_STATE_GETTING,
            SIMULATION_STATE_SETTING, SIMULATION_STATE_PAUSE, STEP_SIMULATION_SINGLE,
            STEP_SIMULATION_MULTIPLE, STEP_SIMULATION_ACTION)
CUSTOM_INFO = ('rft_sim (rft_sim_ros): MuJoCo with granular resistive force theory. A step '
               'is one publish period of sim time; a reset keeps sim time running forward.')
_STATE_NAMES = {STATE_STOPPED: 'stopped', STATE_PLAYING: 'playing', STATE_PAUSED: 'paused'}


@dataclass(frozen=True)
class Answer:
    """A service's simulation_interfaces/Result (`result`, `message`) and, for
    GetSimulationState, the `state`."""
    result: int
    message: str = ''
    state: int = None


class SimulationServices:
    """simulation_interfaces answers for `runtime` (a SimRuntime)."""

    def __init__(self, runtime):
        self._runtime = runtime

    @staticmethod
    def features():
        """(features, spawn formats, custom_info) of GetSimulatorFeatures."""
        return list(FEATURES), [], CUSTOM_INFO

    def reset(self, scope):
        """ResetSimulation with `scope` (bits)."""
        everything = scope in (SCOPE_DEFAULT, SCOPE_ALL)
        if not everything and not scope & SCOPE_STATE:
            if scope & SCOPE_TIME:
                return Answer(RESULT_FEATURE_UNSUPPORTED, 'sim time does not go back (a ROS '
                                                          'clock never does): reset with '
                                                          'SCOPE_STATE')
            if scope & ~SCOPE_SPAWNED:
                return Answer(RESULT_FEATURE_UNSUPPORTED, f'scope {scope}: none of '
                                                          'SCOPE_TIME, _STATE, _SPAWNED')
            return Answer(RESULT_OK, 'nothing is spawned in this simulator: nothing removed, '
                                     'nothing reset')
        done = self._runtime.reset()
        if not done.success:
            return Answer(RESULT_OPERATION_FAILED, done.message)
        note = '; sim time keeps running forward' if everything or scope & SCOPE_TIME else ''
        return Answer(RESULT_OK, done.message + note)

    def step(self, steps, feedback=None):
        """StepSimulation (and SimulateSteps) of `steps` loop iterations (publish periods);
        only while paused. feedback: called (completed steps, remaining steps) after each."""
        runtime = self._runtime
        if steps < 1:
            return Answer(RESULT_OPERATION_FAILED, f'steps must be >= 1, got {steps}')
        if not runtime.paused:
            return Answer(RESULT_OPERATION_FAILED, 'the simulation is playing: pause it first '
                                                   '(SetSimulationState STATE_PAUSED)')
        before = runtime.sim.time
        for done in range(steps):
            stepped = runtime.step()
            if not stepped.success:
                return Answer(RESULT_OPERATION_FAILED,
                              f'after {done} of {steps} steps: {stepped.message}')
            if feedback is not None:
                feedback(done + 1, steps - done - 1)
        return Answer(RESULT_OK, f'{steps} step{"s" if steps > 1 else ""}: '
                                 f'{runtime.sim.time - before:.6g} s to sim time '
                                 f'{runtime.sim.time:.6f} s')

    def state(self):
        """GetSimulationState: STOPPED, PAUSED or PLAYING."""
        return Answer(RESULT_OK, state=self._state())

    def _state(self):
        if not self._runtime.paused:
            return STATE_PLAYING
        return STATE_STOPPED if self._runtime.stopped else STATE_PAUSED

    def set_state(self, state):
        """SetSimulationState to `state`."""
        if state not in _STATE_NAMES:
            return Answer(RESULT_FEATURE_UNSUPPORTED, f'state {state} is not supported: '
                                                      'stopped (0), playing (1) or paused (2)')
        if state == self._state():
            return Answer(ALREADY_IN_TARGET_STATE, f'already {_STATE_NAMES[state]}')
        runtime = self._runtime
        if state == STATE_PLAYING:
            done = runtime.pause(False)
            if not done.success:
                return Answer(STATE_TRANSITION_ERROR, done.message)
            return Answer(RESULT_OK, done.message)
        runtime.pause(True)
        if state == STATE_PAUSED:  # (from STOPPED too: paused, as it stands)
            runtime.stopped = False
            return Answer(RESULT_OK, f'paused at sim time {runtime.sim.time:.6f} s')
        done = runtime.reset()
        return Answer(RESULT_OK, f'stopped: {done.message}')
