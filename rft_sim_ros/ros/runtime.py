"""ROS-free core of the `rft_sim` node: every decision the node makes, none of the wiring.

`SimRuntime` owns a `Simulation` and a sink (anything with `write_state(SimState)` and
`write_diagnostics(SimState, RunStatus)`: the node's publishers, or a `BagWriter`). The
rclpy node only forwards events to it:

* `tick()` on a wall-clock timer (period `tick_period`): runs the publish cycles that are
  due (`Pacer`), each one publish period of sim time (whole steps, exact rate on average:
  `PublishSchedule`) followed by one state publication,
  for at most `tick_budget_s` of wall time so the executor stays responsive, then
  /diagnostics when due (`DiagnosticsSchedule`, wall seconds). Before each cycle it calls
  `take_commands` (the node: it takes the messages its command subscriptions hold and hands
  them to the `on_*` below), so a command takes effect at the next cycle, however many
  cycles the tick runs. The first tick publishes the initial state.
* `on_trajectory(msg)` / `on_positions(msg)` / `on_velocities(msg)` / `on_efforts(msg)` /
  `on_joint_commands(msg)` (sensor_msgs/JointState of ros2_control's topic hardware
  interface: `control.joint_state_commands`, hybrid mode):
  incoming commands (any message backend) go to `sim.commands` at the current sim time;
  bad ones are rejected with a throttled warning naming the problem and counted per reason
  (reported on /diagnostics). Never raises.
* `goal_problem(msg)` / `start_goal(msg, listener)`: FollowJointTrajectory goals
  (`trajectory_goals`), one at a time: the action server asks whether to accept a goal,
  then starts it. The goal's trajectory runs like one on the topic; after each publish
  cycle the goal is checked against its tolerances, its listener gets the feedback and, at
  the end, the outcome. A new goal or any accepted command preempts it (aborted,
  INVALID_GOAL, as joint_trajectory_controller aborts a preempted goal), as do reset and
  divergence; a cancel the listener reports is served at the next tick, paused or not.
* `parameter_problem` / `set_parameter`: checks and applies zeta, real_time_factor, paused,
  joint_gains.
* `pause(flag)`, `reset()`, `step()`, `reset_terrain()`: the services, each answering a
  `ServiceResult` (`messages`).
* `resend_terrain(cloud=..., markers=...)`: a subscriber of the terrain cloud or of its
  markers joined.

With a `terrain.TerrainFeed`, each state publication is followed by the sand surface when it
is due and changed (the sink's `write_terrain(TerrainUpdate)`); `reset()` and
`reset_terrain()` publish the surface's change at once, paused or not, and
`resend_terrain` the whole cloud or the whole set of markers.

A diverging simulation (SimulationDiverged) is logged as an error, reported on /diagnostics
(level ERROR) and pauses the runtime; nothing is published for the failed cycle, and it can
only resume after `reset()`. Times in s (sim time unless said otherwise).
"""
import math
import time
from collections import Counter

from rft_sim_ros.ros import inbound, parameters, topics
from rft_sim_ros.ros.diagnostics import DiagnosticsSchedule, RateMeter, status_key
from rft_sim_ros.ros.messages import RunStatus, ServiceResult
from rft_sim_ros.ros.pacing import Pacer
from rft_sim_ros.control import trajectory_goals as goals
from rft_sim_ros.control.commands import CommandRejected, CommandResult, Reason, Targets
from rft_sim_ros.control.hybrid import gain_patterns
from rft_sim_ros.control.joint_state_commands import read_joint_state_command
from rft_sim_ros.sim.publishing import PublishSchedule
from rft_sim_ros.sim.simulation import SimulationDiverged
from rft_sim_ros.control.throttle import ThrottledLog


def array_order(servo_joints, joint_names):
    """Indices that reorder an array command given in `joint_names` order into
    `servo_joints` order; raises ValueError unless `joint_names` lists every servo joint
    exactly once (as forward_position_controller, which commands all its joints)."""
    joint_names = tuple(str(n) for n in joint_names)
    if sorted(joint_names) != sorted(servo_joints):
        raise ValueError(f'joint_names must list each commanded joint of the scene once '
                         f'({", ".join(servo_joints) or "none"}), got {list(joint_names)}')
    return tuple(joint_names.index(name) for name in servo_joints)


class SimRuntime:
    """Drives `sim` for the node and decides what it publishes (see module docstring).

    publish_rate: state publications per second of sim time (on average: each cycle is a
    whole number of steps, `PublishSchedule`). joint_names: order of array commands (None: the
    scene's commanded joints, Simulation.servo_joint_names). trajectory_controller: the name of
    the joint_trajectory_controller served; namespace: the node's ('/' or '/go2'): the
    command topics and the action are named as they resolve there in warnings and goal
    outcomes. plates: publish active plates.
    terrain: a `terrain.TerrainFeed` of the sim's surface, or None. warn, error: log
    functions (str). clock: wall time, s (monotonic). tick_budget_s: wall time one tick may
    spend stepping. diagnostics_period_s: wall s between /diagnostics. warn_period_s:
    throttle of the rejected-command warnings (one line per reason and topic per period).
    """

    def __init__(self, sim, sink, *, publish_rate, joint_names=None,
                 trajectory_controller=topics.TRAJECTORY_CONTROLLER, namespace='/',
                 joint_commands_topic=topics.ROBOT_JOINT_COMMANDS, real_time_factor=1.0,
                 paused=False, plates=False, terrain=None, warn=print, error=print,
                 clock=time.monotonic, tick_budget_s=0.05, diagnostics_period_s=1.0,
                 warn_period_s=2.0):
        self.sim = sim
        self._sink = sink
        self._publishing = PublishSchedule(parameters.publish_rate(publish_rate), sim.timestep)
        self._cycles = 0  # publish cycles run so far
        servo_joints = tuple(sim.servo_joint_names)
        self.joint_names = servo_joints if joint_names is None else tuple(joint_names)
        self._array_order = array_order(servo_joints, self.joint_names)
        controller = parameters.trajectory_controller(trajectory_controller)
        self.trajectory_topic = topics.trajectory_topic(controller)
        self.trajectory_action = topics.follow_trajectory_action(controller)
        self._namespace = namespace
        self.joint_commands_topic = joint_commands_topic
        self.plates = bool(plates)
        self._terrain = terrain
        self._clock = clock
        self._error = error
        self._warn_once = warn  # lines the simulation itself says once (run_warnings)
        self._warn = ThrottledLog(warn, warn_period_s, clock=clock)
        self._budget = float(tick_budget_s)
        self._pacer = Pacer(real_time_factor)
        self._pacer.restart(clock(), sim.time)
        self._schedule = DiagnosticsSchedule(diagnostics_period_s)
        self._meter = RateMeter()
        self._meter.rate(sim.time, clock())
        self._rejections = Counter()
        self.paused = bool(paused)
        #: paused at the scene's initial state: started paused, or reset while paused, and
        #: not stepped or played since (simulation_interfaces' STOPPED)
        self.stopped = self.paused
        self.diverged = None
        self.last_state = None
        self._goal = None  # (FollowedGoal, listener) of the goal being followed
        self._command_index = {name: i for i, name in enumerate(servo_joints)}
        # indices of the servo joints among a SimState's joints
        self._servo_in_state = [sim.joint_names.index(name) for name in servo_joints]

    # --- properties -------------------------------------------------------------------------

    @property
    def publish_period(self):
        """Mean sim time between state publications, s (1 / publish_rate)."""
        return self._publishing.period

    def _next_cycle_steps(self):
        return self._publishing.steps(self._cycles + 1)

    @property
    def real_time_factor(self):
        """Requested sim seconds per wall second (0 = as fast as possible)."""
        return self._pacer.real_time_factor

    @property
    def tick_period(self):
        """Wall seconds between the node's timer ticks at the current real-time factor."""
        return self._pacer.tick_period(self.publish_period)

    @property
    def rejections(self):
        """{reason: count} of rejected commands since the start (kept across resets)."""
        return dict(self._rejections)

    def status(self, real_time_factor=math.nan):
        """The run's `RunStatus` (for /diagnostics), with a measured real-time factor."""
        return RunStatus(scene=self.sim.scene.name, real_time_factor=real_time_factor,
                         stable=self.diverged is None, problem=self.diverged or '',
                         commands_rejected=self.rejections, paused=self.paused,
                         outcome=self.sim.outcome(), kernels=self.sim.kernels)

    # --- stepping and publishing ------------------------------------------------------------

    def tick(self, take_commands=None):
        """Run the publish cycles due now (within the tick budget), each after
        `take_commands()` (None: nothing to take), then /diagnostics if due."""
        started = self._clock()
        if self.last_state is None:
            self._publish_state()
        if self._goal is not None and self._goal[1].cancel_requested():
            self._end_goal(goals.canceled(), hold=True)
        now = started
        while (not self.paused and now - started < self._budget
               and self._pacer.due(now, self.sim.time
                                   + self._next_cycle_steps() * self.sim.timestep)):
            if take_commands is not None:
                take_commands()
            self._cycle()
            now = self._clock()
        self._diagnostics(now)

    def _cycle(self):
        """Step one publish period and publish the state, or pause on divergence."""
        steps = self._next_cycle_steps()
        try:
            self.sim.step(steps)
        except SimulationDiverged as diverged:
            self.diverged = str(diverged)
            self.paused = True
            self._error(f'simulation diverged {self.diverged}; paused, nothing more is '
                        'published until reset')
            self._end_goal(goals.aborted(f'the simulation diverged {self.diverged}'))
            return False
        self._cycles += 1
        self._publish_state()
        return True

    def _publish_state(self):
        self.last_state = self.sim.state(with_plates=self.plates)
        self._sink.write_state(self.last_state)
        self._publish_terrain()
        for line in self.sim.run_warnings():
            self._warn_once(line)
        self._check_goal()

    def _publish_terrain(self, due=False):
        """Publish the sand surface if it changed and is due (`due`: whatever the rate)."""
        update = self._terrain.update(self.sim.time, due) if self._terrain is not None else None
        if update is not None:
            self._sink.write_terrain(update)

    def resend_terrain(self, *, cloud=False, markers=False):
        """A subscriber of the terrain cloud (`cloud`) or of its markers (`markers`) joined:
        publish the whole cloud, or every marker tile, at once, paused or not, stamped with
        the current sim time (with the changes since the last publication, if any). Before
        the initial publication, and after a divergence (until reset), nothing is
        published: the next publication carries it."""
        if self._terrain is None:
            return
        if cloud:
            self._terrain.resend_cloud()
        if markers:
            self._terrain.resend_markers()
        if self.last_state is not None and self.diverged is None:
            self._publish_terrain(due=True)

    def _diagnostics(self, now):
        key = status_key(self.last_state.zeta, self.diverged is None, self.paused, self.sim.down)
        if self._schedule.due(now, key):
            rate = self._meter.rate(self.last_state.time, now)
            self._sink.write_diagnostics(self.last_state, self.status(0.0 if self.paused else rate))

    # --- commands ---------------------------------------------------------------------------

    def on_trajectory(self, msg):
        """A trajectory_msgs/JointTrajectory for the servos; returns the CommandResult."""
        try:
            command = inbound.trajectory_command(msg)
        except (AttributeError, TypeError, ValueError) as error:
            result = CommandResult(Reason.MALFORMED, f'not a joint trajectory ({error})')
        else:
            if self.sim.commands is None:
                result = CommandResult(Reason.UNKNOWN_JOINT, 'this scene has no position '
                                       'servos to command')
            else:
                result = self.sim.commands.set_trajectory(command, now=self.sim.time)
        return self._outcome(self.trajectory_topic, result)

    def on_positions(self, msg):
        """A std_msgs/Float64MultiArray of positions in `joint_names` order (rad or m)."""
        return self._on_array(msg, 'position', topics.POSITION_COMMANDS)

    def on_velocities(self, msg):
        """A std_msgs/Float64MultiArray of velocities in `joint_names` order (rad/s or m/s),
        as ros2_control's velocity forward controller takes them."""
        return self._on_array(msg, 'velocity', topics.VELOCITY_COMMANDS)

    def on_efforts(self, msg):
        """A std_msgs/Float64MultiArray of efforts in `joint_names` order (N m or N), as
        ros2_control's effort forward controller takes them."""
        return self._on_array(msg, 'effort', topics.EFFORT_COMMANDS)

    def on_joint_commands(self, msg):
        """A sensor_msgs/JointState command as ros2_control's topic hardware interface sends
        it (`control.joint_state_commands`; the interfaces of the robot's <ros2_control>
        block read its packed arrays): hybrid mode (`control.hybrid`)."""
        commands = self.sim.commands
        if commands is None:
            result = CommandResult(Reason.UNKNOWN_JOINT, self.sim.no_commands_reason())
        else:
            try:
                command = read_joint_state_command(msg, self._command_index,
                                                   self.sim.description.command_interfaces,
                                                   self.sim.passive_joint_names)
            except CommandRejected as rejected:
                result = rejected.result
            else:
                result = commands.set_joint_states(command, now=self.sim.time)
        return self._outcome(self.joint_commands_topic, result)

    def _on_array(self, msg, kind, topic):
        try:
            values = inbound.array_command(msg)
        except (AttributeError, TypeError, ValueError) as error:
            result = CommandResult(Reason.MALFORMED, f'not a {kind} array ({error})')
        else:
            if self.sim.commands is None:
                result = CommandResult(Reason.ARRAY_LENGTH, f'{kind} command has '
                                       f'{len(values)} values, but this scene has no '
                                       'commanded joints')
            else:
                if len(values) == len(self._array_order):
                    values = [values[i] for i in self._array_order]
                commands = self.sim.commands
                apply = {'position': commands.set_positions, 'velocity': commands.set_velocities,
                         'effort': commands.set_efforts}[kind]
                result = apply(values, now=self.sim.time)
        return self._outcome(topic, result)

    def _outcome(self, topic, result):
        topic = topics.resolved(topic, self._namespace)
        if not result.accepted:
            self._rejections[result.reason.value] += 1
            self._warn((topic, result.reason), f'rejected command on {topic}: {result.message}')
        else:
            self._end_goal(goals.aborted(f'preempted by a new command on {topic}'))
        return result

    # --- FollowJointTrajectory goals ---------------------------------------------------------

    def _goal_request(self, msg):
        """(CommandResult, GoalRequest, Tolerances) of a goal message; the result says why
        it cannot be followed (then the others are None), else it is the trajectory's
        verdict from `check_trajectory`."""
        try:
            request = inbound.follow_goal(msg)
        except (AttributeError, TypeError, ValueError) as error:
            malformed = f'not a FollowJointTrajectory goal ({error})'
            return CommandResult(Reason.MALFORMED, malformed), None, None
        if self.sim.commands is None:
            return CommandResult(Reason.UNKNOWN_JOINT, 'this scene has no position servos to '
                                 'command'), None, None
        try:
            tolerances = goals.goal_tolerances(request, self.sim.commands.joint_names)
        except ValueError as error:
            return CommandResult(Reason.GOAL, str(error)), None, None
        return (self.sim.commands.check_trajectory(request.trajectory, now=self.sim.time),
                request, tolerances)

    def goal_problem(self, msg):
        """Why the FollowJointTrajectory goal `msg` (any message backend) cannot be
        accepted now, or None; a refused goal is logged and counted as a rejected command."""
        result = self._goal_request(msg)[0]
        if not result.accepted:
            self._outcome(self.trajectory_action, result)
            return result.message
        return None

    def start_goal(self, msg, listener):
        """Follow the accepted goal `msg` from now on, preempting the one being followed.

        listener: receives `publish_feedback(GoalFeedback)` after every publish cycle and, once,
        `finish(GoalOutcome)`; `cancel_requested()` says whether its client asked to cancel.
        A goal that has become invalid since it was accepted (its trajectory now ends in the
        past) finishes at once, aborted with the matching error code.
        """
        result, request, tolerances = self._goal_request(msg)
        if result.accepted:
            result = self.sim.commands.set_trajectory(request.trajectory, now=self.sim.time)
        self._outcome(self.trajectory_action, result)
        if not result.accepted:
            listener.finish(goals.GoalOutcome(goals.GoalState.ABORTED,
                                              goals.error_code(result.reason), result.message))
            return
        start, end = result.span
        self._goal = (goals.FollowedGoal(tolerances, start, end, self.sim.commands.joint_names),
                      listener)

    def _servo_targets(self, state):
        """`Targets` of the servo joints' actual positions and velocities in `state`."""
        index = self._servo_in_state
        return Targets(state.joint_positions[index], state.joint_velocities[index])

    def _check_goal(self):
        """Feedback of the goal being followed for the state just published, and its end
        if it ends now (a goal ended by a tolerance leaves the joints holding)."""
        if self._goal is None:
            return
        goal, listener = self._goal
        feedback, outcome = goal.check(self.last_state.time,
                                       self.sim.commands.sample(self.sim.time),
                                       self._servo_targets(self.last_state))
        listener.publish_feedback(feedback)
        if outcome is not None:
            self._end_goal(outcome, hold=outcome.state is not goals.GoalState.SUCCEEDED)

    def _end_goal(self, outcome, hold=False):
        """End the goal being followed (if any) with `outcome` (logged as a warning if it
        is aborted); hold: its joints hold the positions last published."""
        if self._goal is None:
            return
        listener, self._goal = self._goal[1], None
        if hold:
            self.sim.commands.hold_positions(self._servo_targets(self.last_state).positions,
                                             self.sim.time)
        if outcome.state is goals.GoalState.ABORTED:
            action = topics.resolved(self.trajectory_action, self._namespace)
            self._warn_once(f'{action} goal aborted ({outcome.error_code.name}): '
                            f'{outcome.message}')
        listener.finish(outcome)

    # --- parameters -------------------------------------------------------------------------

    def parameter_problem(self, name, value):
        """Why parameter `name` cannot take `value` now, or None (see `parameters`)."""
        problem = parameters.parameter_problem(name, value)
        if problem is None and name == parameters.PAUSED and not value and self.diverged:
            problem = self._diverged_problem()
        return problem

    def set_parameter(self, name, value):
        """Apply a dynamic parameter accepted by `parameter_problem`."""
        if name == parameters.ZETA:
            self.sim.zeta = float(value)
        elif name == parameters.REAL_TIME_FACTOR:
            self._pacer.set_real_time_factor(float(value), self._clock(), self.sim.time)
        elif name == parameters.PAUSED:
            self._set_paused(bool(value))
        elif name == parameters.JOINT_GAINS:
            self.sim.hybrid_drive.set_gains(gain_patterns(list(value)))
        else:
            raise KeyError(f'{name} cannot change while the node runs')

    def _set_paused(self, paused):
        if paused != self.paused:
            self.paused = paused
            if not paused:
                self.stopped = False
                self._pacer.restart(self._clock(), self.sim.time)

    def _diverged_problem(self):
        return f'the simulation diverged ({self.diverged}): call reset first'

    # --- services ---------------------------------------------------------------------------

    def pause(self, paused):
        """std_srvs/SetBool `pause`: True pauses, False resumes (refused after divergence)."""
        if not paused and self.diverged:
            return ServiceResult(False, self._diverged_problem())
        self._set_paused(bool(paused))
        return ServiceResult(True, f'{"paused" if paused else "running"} at sim time '
                                   f'{self.sim.time:.6f} s')

    def step(self):
        """std_srvs/Trigger `step`: while paused, advance one publish period and publish."""
        if self.diverged:
            return ServiceResult(False, self._diverged_problem())
        if not self.paused:
            return ServiceResult(False, 'step works while paused: call pause (true) first')
        before = self.sim.time
        self.stopped = False
        stepped = self._cycle()
        self._diagnostics(self._clock())
        if not stepped:
            return ServiceResult(False, f'simulation diverged {self.diverged}')
        return ServiceResult(True, f'stepped {self.sim.time - before:.6g} s to sim time '
                                   f'{self.sim.time:.6f} s')

    def reset(self):
        """std_srvs/Trigger `reset`: back to the scene's initial state; sim time keeps
        running forward; commands are dropped; paused stays as it is (and a reset while
        paused is `stopped`). The sand surface, if that changed, is published at once; the
        state with the next cycle."""
        self.sim.reset()
        self.stopped = self.paused
        self._end_goal(goals.aborted('the simulation was reset'))
        self.diverged = None
        self._pacer.restart(self._clock(), self.sim.time)
        self._publish_terrain(due=True)
        return ServiceResult(True, f'reset at sim time {self.sim.time:.6f} s '
                                   f'({"paused" if self.paused else "running"})')

    def reset_terrain(self):
        """std_srvs/Trigger `reset_terrain`: deformable sand back to its pristine surface,
        nothing else changes (sim time, robot, commands); the change is published at once,
        paused or not, stamped with the current sim time. Refused (success False: nothing
        was done) where the sand is not deformable."""
        if not self.sim.engine.deformable:
            return ServiceResult(False, 'the sand of this scene is not deformable: nothing to '
                                        'reset')
        self.sim.reset_terrain()
        self._publish_terrain(due=True)
        return ServiceResult(True, f'sand surface reset at sim time {self.sim.time:.6f} s')
