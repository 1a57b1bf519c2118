"""The `rft_sim` node (`ros2 run rft_sim_ros sim`): rclpy wiring around `SimRuntime`.

This module only connects ROS entities to `rft_sim_ros.ros.runtime.SimRuntime`, which makes
every decision (pacing, checks, command dispatch, what to publish when). Interface
(docs/ros.md): parameters of `rft_sim_ros.ros.parameters`; publishers of
`topics.published_topics`; subscriptions to the ros2_control command topics; the topic
hardware interface's JointState commands and state (parameters joint_commands_topic,
joint_states_topic);
joint_trajectory_controller's FollowJointTrajectory action server (control_msgs); services
~/pause (std_srvs/SetBool), ~/reset, ~/step and ~/reset_terrain (std_srvs/Trigger);
simulation_interfaces' get_simulator_features, reset_simulation, step_simulation,
get_simulation_state and set_simulation_state services and simulate_steps action where that
package is installed (`simulation_services`). The
robot comes from the parameters scene / model / robot_description, or, with none of them
set, from the first valid message on /robot_description (rft_sim_ros.ros.robot_source). The
node publishes /clock itself and must not run on sim time; its timer runs on the steady
wall clock.

Start-up (`rft_sim_ros.ros.startup`): this module imports rclpy and the node's light
modules only, so the node is on the graph and answers before the simulation's modules are
imported (seconds on a busy machine); the scene is read
(the simulation's modules imported: MuJoCo, the engine, numba where the kernels are not
prebuilt) and the simulation built (its
kernels compiled on a cold cache) in a worker thread while the dynamic parameters, the
services and /diagnostics already answer; a bad scene or parameter stops the node once
read; the topics, the subscriptions and the action come once it is built, and it starts
with the parameters as they are then.
"""
import sys
import tempfile
from pathlib import Path

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.exceptions import InvalidHandle
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future

from rft_sim_ros.control.trajectory_goals import GoalState
from rft_sim_ros.ros import follow_messages, messages, parameters, simulation_services, topics
from rft_sim_ros.ros.diagnostics import DiagnosticsSchedule
from rft_sim_ros.ros.entry import run_node
from rft_sim_ros.ros.factory import RclpyFactory
from rft_sim_ros.ros.messages import ServiceResult
from rft_sim_ros.ros.startup import SimStartup, StartFailed, compile_in_child

NODE_NAME = 'rft_sim'
#: Where robot_description strings are stored as files for the scene to name.
DESCRIPTION_FOLDER = Path(tempfile.gettempdir()) / 'rft_sim_ros' / 'robot_description'
QUEUE_DEPTH = 10
#: Wall s between the start-up timer's looks at the simulation being built, and between its
#: /diagnostics (and at once when zeta or paused change meanwhile).
STARTUP_POLL_S = 0.1
STARTUP_DIAGNOSTICS_PERIOD_S = 1.0
#: s of wall time between two looks for another publisher of /clock (`_check_clock`).
CLOCK_CHECK_PERIOD_S = 2.0
#: Sim time of the start-up's /diagnostics stamps: the simulation's start, s.
START_TIME = 0.0
TF_QUEUE_DEPTH = 100  # as tf2_ros.TransformBroadcaster

#: Parameters of type double. They accept integers too (`ros2 param set /rft_sim zeta 2`,
#: `-p zeta:=2`), taken as doubles (`_as_doubles`), so their type stays double.
_DOUBLES = (parameters.ZETA, parameters.REAL_TIME_FACTOR, parameters.PUBLISH_RATE,
            parameters.TERRAIN_RATE)


def _as_doubles(changes):
    """The rclpy Parameters `changes`, those of `_DOUBLES` with an integer value made
    doubles of the same value (a pre-set parameters callback)."""
    return [Parameter(change.name, Parameter.Type.DOUBLE, float(change.value))
            if change.name in _DOUBLES and change.type_ == Parameter.Type.INTEGER else change
            for change in changes]


def read_scene(robot, robot_description, assignments, keyframe):
    """The SceneConfig the node's parameters ask for: `robot` {scene, model, sand_bodies:
    the parameters}, `robot_description` (XML or ''), `assignments` (scene_overrides) and
    `keyframe` (`robot_source.load_node_scene`); raises SceneError or ValueError. Called
    in the start-up thread: it imports the simulation's side of the node (MuJoCo, the sand
    engine, the runtime, numba where the kernels are not prebuilt: up to seconds on a busy
    two-core machine), so the node is on the graph
    and answers meanwhile, and the executor thread, which never imports them itself, finds
    them imported once the scene is read."""
    from rft_sim_ros.ros import runtime, terrain  # noqa: F401  (for `_serve`: see above)
    from rft_sim_ros.ros.robot_source import load_node_scene, scene_overrides
    overrides = scene_overrides(assignments)
    for sensor in ('sensors.imu', 'sensors.contacts'):  # (on in the node unless set off)
        overrides.setdefault(sensor, True)
    if keyframe:
        overrides['robot.keyframe'] = keyframe
    return load_node_scene(robot[parameters.SCENE], robot[parameters.MODEL], robot_description,
                           robot[parameters.SAND_BODIES], overrides, DESCRIPTION_FOLDER)


def build_simulation(scene):
    """The Simulation of `scene` (in the start-up thread: its kernels compile if not cached)."""
    from rft_sim_ros.sim.simulation import Simulation
    return Simulation(scene)


def _compile_notice(scene):
    from rft_sim_ros.sim.simulation import compile_notice
    return compile_notice(scene)


class SimNode(Node):
    """Loads the scene named by its parameters and serves it over ROS (see module docstring).

    Raises ValueError or rclpy's ParameterException (the message says what to fix) if a
    parameter it checks at once (zeta, real_time_factor, paused) is unusable; a scene that
    cannot be read or built, or a parameter checked against it, raises StartFailed from the
    executor, once the start-up thread got that far. `starting` says whether it is starting.
    """

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.add_pre_set_parameters_callback(_as_doubles)
        # rclpy declares a parameter from its start-up value without the pre-set callbacks
        self._parameter_overrides.update(
            (change.name, change) for change in _as_doubles(self._parameter_overrides.values()))
        self.runtime = None
        self._startup = None
        self._scene = None
        self._description_subscription = None
        self._topic_publishers = {}
        self._factory = RclpyFactory()
        self._robot = {name: self._declare(name, '') for name in (
            parameters.SCENE, parameters.MODEL, parameters.ROBOT_DESCRIPTION,
            parameters.SAND_BODIES)}
        self._assignments = self._declare(parameters.SCENE_OVERRIDES,
                                          Parameter.Type.STRING_ARRAY) or []
        self._keyframe = self._declare(parameters.KEYFRAME, '')
        self._video_file = parameters.video_file(self._declare(parameters.VIDEO_PATH, ''))
        self._video = None
        if self._video_file is not None:  # (before the build: no frame, no simulation)
            from rft_sim_ros.render.gl import check_offscreen
            check_offscreen()
        if parameters.needs_topic(self._robot[parameters.SCENE], self._robot[parameters.MODEL],
                                  self._robot[parameters.ROBOT_DESCRIPTION]):
            self.get_logger().info(f'no scene, model or robot_description set: waiting for '
                                   f'the robot on {topics.ROBOT_DESCRIPTION}')
            latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                                 reliability=ReliabilityPolicy.RELIABLE)
            self._description_subscription = self.create_subscription(
                self._factory.message_class(topics.ROBOT_DESCRIPTION_TYPE),
                topics.relative(topics.ROBOT_DESCRIPTION), self._on_robot_description, latched)
            return
        self._start(self._robot[parameters.ROBOT_DESCRIPTION])

    def _on_robot_description(self, message):
        """A /robot_description message: load the robot and start serving it, unless one
        is served or being built already."""
        if self.runtime is not None or self.starting:
            return
        try:
            self._start(message.data)
        except ValueError as error:
            self._wait_for_another(error)

    def _wait_for_another(self, error):
        self.get_logger().error(f'cannot start from {topics.ROBOT_DESCRIPTION}: {error}; '
                                'waiting for another description')

    def _start(self, robot_description):
        """Serve at once what needs no simulation (the dynamic parameters, the services,
        /diagnostics) while the start-up thread reads the scene the parameters (and
        `robot_description`, XML or '') ask for and builds its simulation (`startup`:
        kernels compile on a cold cache); `_poll_startup` reads the parameters that depend
        on the scene once it is read, and serves the rest once it is built. zeta unset
        (no -p zeta) is the scene's once read."""
        initial = {name: self._declare(name, default) for name, default in (
            (parameters.ZETA, Parameter.Type.DOUBLE), (parameters.REAL_TIME_FACTOR, 1.0),
            (parameters.PAUSED, False))}
        for name, value in initial.items():
            problem = parameters.parameter_problem(name, value) if value is not None else None
            if problem:
                raise ValueError(problem)
        self._scene = None
        self._scene_name = (self._robot[parameters.SCENE] or self._robot[parameters.MODEL]
                            or parameters.ROBOT_DESCRIPTION)
        if not self._topic_publishers:  # (a description from the topic may come again)
            self._serve_while_starting()
        self._startup_schedule = DiagnosticsSchedule(STARTUP_DIAGNOSTICS_PERIOD_S)
        self._timer = self.create_timer(STARTUP_POLL_S, self._poll_startup,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))
        robot = dict(self._robot)  # (the thread starts last: its imports compete for the GIL)
        self._startup = SimStartup(
            lambda: read_scene(robot, robot_description, self._assignments, self._keyframe),
            build_simulation, notice=_compile_notice, warm=compile_in_child,
            errors=(ValueError,))

    def _serve_while_starting(self):
        """/diagnostics, the services and the parameter checks: served from the start."""
        self._topic_publishers[topics.DIAGNOSTICS] = self.create_publisher(
            self._factory.message_class(topics.DIAGNOSTICS_TYPE),
            topics.relative(topics.DIAGNOSTICS), QUEUE_DEPTH)
        set_bool = self._factory.message_class('std_srvs/srv/SetBool')
        trigger = self._factory.message_class('std_srvs/srv/Trigger')
        self.create_service(set_bool, '~/pause', self._on_pause)
        for name in ('reset', 'step', 'reset_terrain'):
            self.create_service(trigger, f'~/{name}',
                                lambda req, res, name=name: self._on_trigger(name, res))
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)

    def _read_scene_parameters(self, scene):
        """The scene is read: zeta from it where unset, and the static parameters whose
        default is the scene's or that need no simulation, checked now (a bad one stops the
        node before the simulation is built). Raises StartFailed."""
        from rft_sim_ros.ros.terrain import DEFAULT_RATE  # (imported: `read_scene`)
        self._scene, self._scene_name = scene, scene.name
        try:
            if self._value(parameters.ZETA) is None:
                outcome = self.set_parameters([Parameter(parameters.ZETA,
                                                         value=float(scene.zeta))])[0]
                if not outcome.successful:
                    raise ValueError(outcome.reason)
            self._plates = self._declare(parameters.PLATES, False)
            self._publish_rate = self._declare(parameters.PUBLISH_RATE, scene.publish_rate)
            parameters.publish_rate(self._publish_rate)
            self._terrain_rate = self._declare(parameters.TERRAIN_RATE, DEFAULT_RATE)
            parameters.publish_rate(self._terrain_rate, parameters.TERRAIN_RATE)
            self._trajectory_controller = self._declare(parameters.TRAJECTORY_CONTROLLER,
                                                        topics.TRAJECTORY_CONTROLLER)
            parameters.trajectory_controller(self._trajectory_controller)
        except ValueError as error:
            raise StartFailed(str(error)) from error
        notice = self._startup.notice
        self.get_logger().info(f'scene {scene.name}: building the simulation'
                               f'{f" ({notice})" if notice else ""}; parameters, services and '
                               '/diagnostics answer meanwhile')

    def _poll_startup(self):
        """Start-up timer: /diagnostics while the simulation is being built; the scene's
        parameters once it is read; once built, serve it with the parameters as they are
        now. Raises StartFailed if it could not be read or built, or a parameter does not
        fit it (a description from the topic: logged, and the node waits for another)."""
        try:
            if self._scene is None and self._startup.scene is not None:
                self._read_scene_parameters(self._startup.scene)
            sim = self._startup.result()
        except StartFailed as error:
            self.destroy_timer(self._timer)
            self._startup = None
            if self._description_subscription is None:
                raise
            self._wait_for_another(error)
            return
        if sim is None:
            zeta, paused = (self._value(name) for name in (parameters.ZETA, parameters.PAUSED))
            if self._startup_schedule.due(self._startup.elapsed(), (zeta, paused)):
                fields = self._startup.diagnostic_fields(self._scene_name, zeta, paused)
                self._topic_publishers[topics.DIAGNOSTICS].publish(
                    messages.diagnostic_array(self._factory, fields, START_TIME))
            return
        self.destroy_timer(self._timer)
        try:
            self._serve(sim)
        except ValueError as error:  # (joint_names that do not fit the scene)
            raise StartFailed(str(error)) from error
        if self._description_subscription is not None:
            self.destroy_subscription(self._description_subscription)
            self._description_subscription = None

    @property
    def starting(self):
        """Whether the simulation is being built (parameters, services and /diagnostics
        answer; nothing else is served yet)."""
        return self._startup is not None and self.runtime is None

    def _serve(self, sim):
        """Serve the built simulation `sim`: its publishers, subscriptions, action and
        timer; it starts with the zeta, real_time_factor and paused set by now."""
        from rft_sim_ros.ros.runtime import SimRuntime  # (imported: `read_scene`)
        from rft_sim_ros.ros.terrain import TerrainFeed
        sim.zeta = float(self.get_parameter(parameters.ZETA).value)
        joint_names = self._declare(parameters.JOINT_NAMES,
                                    list(sim.servo_joint_names) or Parameter.Type.STRING_ARRAY)
        terrain = TerrainFeed(sim.engine.surface, self._terrain_rate)
        # a subscriber joining the cloud gets the whole grid at once, one joining the
        # markers every marker tile (paused too)
        joined = {topics.TERRAIN: self._on_subscriber(cloud=True),
                  topics.TERRAIN_MARKER: self._on_subscriber(markers=True)}
        self._topic_publishers.update({
            topic: self.create_publisher(
                self._factory.message_class(msgtype), topics.relative(topic),
                TF_QUEUE_DEPTH if topic == topics.TF else QUEUE_DEPTH,
                event_callbacks=joined.get(topic))
            for topic, msgtype in topics.published_topics(
                list(sim.legs), plates=self._plates, terrain=terrain.active,
                sensors=sim.sensors.layout).items()
            if topic not in self._topic_publishers})
        self._imu_topic = sim.sensors.imu_topic
        logger = self.get_logger()
        if self._startup.warm_problem:
            logger.warning(f'kernels compiled in the node itself (the compiling process '
                           f'failed: {self._startup.warm_problem}); it answered slowly meanwhile')
        for notice in sim.notices:  # e.g. the sand bodies `auto` chose
            logger.info(notice)
        self.runtime = SimRuntime(
            sim, self, publish_rate=self._publish_rate, joint_names=joint_names,
            trajectory_controller=self._trajectory_controller,
            namespace=self.get_namespace(),
            joint_commands_topic=parameters.topic_name(self._declare(
                parameters.JOINT_COMMANDS_TOPIC, topics.ROBOT_JOINT_COMMANDS),
                parameters.JOINT_COMMANDS_TOPIC),
            real_time_factor=float(self.get_parameter(parameters.REAL_TIME_FACTOR).value),
            paused=self.get_parameter(parameters.PAUSED).value, plates=self._plates,
            terrain=terrain, warn=logger.warning, error=logger.error)
        self._view = self._open_viewer(sim) if self._declare(parameters.VIEWER, False) else None
        if self._video_file is not None:
            from rft_sim_ros.render.recorder import PainterFailed, VideoRecorder
            self._video_failed = PainterFailed
            self._video = VideoRecorder(self._video_file, sim.scene)
            self._video.start(sim)
        self._command_subscriptions = [self.create_subscription(
            self._factory.message_class(msgtype), topics.relative(topic), callback,
            QUEUE_DEPTH) for msgtype, topic, callback in (
                (topics.JOINT_TRAJECTORY_TYPE, self.runtime.trajectory_topic,
                 self.runtime.on_trajectory),
                (topics.POSITION_COMMANDS_TYPE, topics.POSITION_COMMANDS,
                 self.runtime.on_positions),
                (topics.VELOCITY_COMMANDS_TYPE, topics.VELOCITY_COMMANDS,
                 self.runtime.on_velocities),
                (topics.EFFORT_COMMANDS_TYPE, topics.EFFORT_COMMANDS, self.runtime.on_efforts))]
        self._serve_topic_hardware()
        self._serve_follow_joint_trajectory()
        self._serve_simulation_interfaces()
        self._timer = self.create_timer(self.runtime.tick_period, self._tick,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._clock_publishers = 1  # (this node's)
        self._clock_check = self.create_timer(CLOCK_CHECK_PERIOD_S, self._check_clock,
                                              clock=Clock(clock_type=ClockType.STEADY_TIME))
        logger.info(f'scene {sim.scene.name}: built in {self._startup.elapsed():.1f} s; '
                    f'publishing every {self.runtime.publish_period:g} s '
                    f'of sim time at real-time factor {self.runtime.real_time_factor:g}'
                    f'{" (paused)" if self.runtime.paused else ""}')

    def _serve_topic_hardware(self):
        """ros2_control's topic hardware interface: its JointState commands in, the joint
        states out (topics.ROBOT_JOINT_COMMANDS / ROBOT_JOINT_STATES, renamed by parameters),
        and the gains of its hybrid commands."""
        joint_state = self._factory.message_class(topics.JOINT_STATE_TYPE)
        states = parameters.topic_name(self._declare(parameters.JOINT_STATES_TOPIC,
                                                     topics.ROBOT_JOINT_STATES),
                                       parameters.JOINT_STATES_TOPIC)
        self._hardware_states = self.create_publisher(joint_state, topics.relative(states),
                                                      QUEUE_DEPTH)
        self._command_subscriptions.append(self.create_subscription(
            joint_state, topics.relative(self.runtime.joint_commands_topic),
            self.runtime.on_joint_commands, topics.ROBOT_JOINT_COMMANDS_DEPTH))
        gains = self._declare(parameters.JOINT_GAINS, Parameter.Type.STRING_ARRAY)
        if gains:
            problem = self.runtime.parameter_problem(parameters.JOINT_GAINS, gains)
            if problem:
                raise ValueError(problem)
            self.runtime.set_parameter(parameters.JOINT_GAINS, gains)

    def _serve_simulation_interfaces(self):
        """simulation_interfaces' services (`simulation_services`), where the package is
        installed; else said once."""
        try:
            from simulation_interfaces import action, srv
        except ImportError:
            self.get_logger().info('simulation_interfaces is not installed: its simulator '
                                   'services are off (~/pause, ~/step, ~/reset serve instead)')
            return
        services = simulation_services.SimulationServices(self.runtime)

        def answer(response, outcome):
            response.result.result, response.result.error_message = (outcome.result,
                                                                      outcome.message)
            self._sync_paused()
            return response

        def features(request, response):
            (response.features.features, response.features.spawn_formats,
             response.features.custom_info) = services.features()
            return response

        def state(request, response):
            outcome = services.state()
            response.state.state = outcome.state
            return answer(response, outcome)

        for kind, name, callback in (
                (srv.GetSimulatorFeatures, 'get_simulator_features', features),
                (srv.ResetSimulation, 'reset_simulation',
                 lambda request, response: answer(response, services.reset(request.scope))),
                (srv.StepSimulation, 'step_simulation',
                 lambda request, response: answer(response, services.step(request.steps))),
                (srv.GetSimulationState, 'get_simulation_state', state),
                (srv.SetSimulationState, 'set_simulation_state',
                 lambda request, response: answer(response,
                                                   services.set_state(request.state.state)))):
            self.create_service(kind, name, callback)

        def simulate_steps(goal_handle):
            def feedback(completed, remaining):
                goal_handle.publish_feedback(action.SimulateSteps.Feedback(
                    completed_steps=completed, remaining_steps=remaining))
            result = answer(action.SimulateSteps.Result(),
                            services.step(goal_handle.request.steps, feedback))
            if result.result.result == simulation_services.RESULT_OK:
                goal_handle.succeed()
            else:
                goal_handle.abort()
            return result

        self._simulate_steps = ActionServer(self, action.SimulateSteps, 'simulate_steps',
                                            execute_callback=simulate_steps)

    def _on_subscriber(self, **resend):
        """Publisher events: a subscriber joining makes the runtime re-send the terrain
        (`SimRuntime.resend_terrain(**resend)`) at once. The event handler is in the node's
        default callback group, mutually exclusive like the timer, the services and the
        subscriptions (and `rclpy.spin` runs one callback at a time), so it never runs
        during a tick or another callback."""
        return PublisherEventCallbacks(
            matched=lambda info: self.runtime.resend_terrain(**resend)
            if info.current_count_change > 0 else None)

    def _serve_follow_joint_trajectory(self):
        """The FollowJointTrajectory action server, where control_msgs is installed."""
        try:
            action = self._factory.message_class(topics.FOLLOW_JOINT_TRAJECTORY_TYPE)
        except ImportError as error:
            self.get_logger().warning(f'no {self.runtime.trajectory_action} action: '
                                      f'control_msgs is not installed ({error})')
            return
        self._action_server = ActionServer(
            self, action, topics.relative(self.runtime.trajectory_action),
            execute_callback=self._follow_goal,
            goal_callback=self._accept_goal, cancel_callback=lambda goal: CancelResponse.ACCEPT)

    def _accept_goal(self, goal):
        return GoalResponse.REJECT if self.runtime.goal_problem(goal) else GoalResponse.ACCEPT

    async def _follow_goal(self, goal_handle):
        """Execute an accepted goal: the runtime follows it; the result comes when it ends."""
        listener = _GoalListener(self._factory, goal_handle)
        self.runtime.start_goal(goal_handle.request, listener)
        return await listener.result

    def _declare(self, name, default):
        """Declare parameter `name` from its spec; returns its value (None if unset). One
        declared already (a second description from the topic) keeps its value. A string
        list given no value gets the empty list: a parameter without a value makes rclpy's
        GetParameters, so `ros2 param dump`, answer no value at all for any request naming
        it. (rclpy reads a bare [] as a byte array, and refuses to set a read-only one, so
        it is declared writable and typed, set, and then made read-only.)"""
        if self.has_parameter(name):
            return self._value(name)
        spec = parameters.SPECS[name]
        descriptor = ParameterDescriptor(description=spec.description,
                                         read_only=not spec.dynamic)
        if default != Parameter.Type.STRING_ARRAY:
            return self.declare_parameter(name, default, descriptor).value
        value = self.declare_parameter(name, default, ParameterDescriptor(
            description=spec.description)).value  # (writable until it has a value)
        if value is None:  # (`_check_parameters` lets its first value, [], through)
            self.set_parameters([Parameter(name, Parameter.Type.STRING_ARRAY, [])])
        if not spec.dynamic:
            descriptor.type = Parameter.Type.STRING_ARRAY.value
            self.set_descriptor(name, descriptor)
        return [] if value is None else value

    def _value(self, name):
        """The value of declared parameter `name`; None while unset (declared without a
        value: zeta before the scene is read, joint_gains)."""
        parameter = self.get_parameter_or(name)
        return None if parameter is None else parameter.value

    # --- sink of SimRuntime -----------------------------------------------------------------

    def write_state(self, state):
        """Publish one cycle of `state` (SimState)."""
        for topic, message in messages.state_messages(self._factory, state, plates=self._plates,
                                                      imu_topic=self._imu_topic):
            self._topic_publishers[topic].publish(message)
            if topic == topics.JOINT_STATES:
                self._hardware_states.publish(message)
        if self._video is not None:
            try:
                self._video.record(state)
            except self._video_failed as error:  # (the node runs on without its video)
                self.get_logger().error(f'{parameters.VIDEO_PATH}: {error}; recording stopped')
                self._close_video()

    def write_terrain(self, update):
        """Publish the sand surface of `update` (terrain.TerrainUpdate): its cloud and one
        MarkerArray of its markers (`messages.terrain_messages`), each where it has one."""
        for topic, message in messages.terrain_messages(self._factory, update):
            self._topic_publishers[topic].publish(message)

    def write_diagnostics(self, state, status):
        """Publish /diagnostics for `state` and `status` (messages.RunStatus)."""
        self._topic_publishers[topics.DIAGNOSTICS].publish(
            messages.diagnostics_message(self._factory, state, status))

    # --- callbacks --------------------------------------------------------------------------

    def _tick(self):
        self.runtime.tick(self._take_commands)
        self._sync_paused()
        if self._view is not None:
            if self._view.is_running():
                self._view.show()
            else:  # (the window was closed: the node runs on without it)
                self._view = None

    def _check_clock(self):
        """Warn (once each time it starts) when another node publishes this node's /clock:
        a second simulator (another namespace shares the one /clock), or `ros2 bag play
        --clock`. Each drives sim time its own way, so the nodes using sim time see it jump
        back and forth."""
        topic = self._topic_publishers[topics.CLOCK].topic_name
        count = self.count_publishers(topic)
        if count > 1 and self._clock_publishers <= 1:
            self.get_logger().warning(
                f'{count - 1} other publisher{"s" * (count > 2)} of {topic}: another '
                'simulator (a second namespace shares the one /clock) or a bag played with '
                '--clock; each drives sim time its own way, so nodes using sim time see it '
                'jump back and forth. Run one simulator per ROS domain (ROS_DOMAIN_ID)')
        self._clock_publishers = count

    def _take_commands(self):
        """Hand every message the command subscriptions hold to its callback now, in the
        order they were received (across the topics: a position command after an effort
        one leaves the joints in position mode), between two publish cycles of a tick: the
        executor would serve them only after the tick, which runs the cycles due for up to
        its budget (many, where the machine falls behind or runs as fast as it can), and
        then one a subscription between two ticks. Taken as rclpy's executor takes them;
        the callbacks are the runtime's, in this thread."""
        taken = []  # (received, order, callback, message)
        for subscription in self._command_subscriptions:
            while True:
                try:
                    with subscription.handle:
                        message = subscription.handle.take_message(subscription.msg_type,
                                                                   subscription.raw)
                except InvalidHandle:  # (destroyed: the node is shutting down)
                    break
                if message is None:
                    break
                taken.append((message[1]['received_timestamp'], len(taken),
                              subscription.callback, message[0]))
        for _, _, callback, message in sorted(taken, key=lambda item: item[:2]):
            callback(message)

    def _close_video(self):
        """Finish the video (the frames queued are painted first) and say where it is."""
        video, self._video = self._video, None
        try:
            video.close()
            self.get_logger().info(f'{parameters.VIDEO_PATH}: {video.frames} frames in '
                                   f'{video.path}')
        except self._video_failed as error:
            self.get_logger().error(f'{parameters.VIDEO_PATH}: {error}')

    def destroy_node(self):
        """Finish the video, then destroy the node."""
        if self._video is not None:
            self._close_video()
        super().destroy_node()

    def _open_viewer(self, sim):
        """A LiveView window on `sim`, or None (no display: said in one error line)."""
        from rft_sim_ros.render.viewer import LiveView, ViewerUnavailable
        try:
            return LiveView(sim)
        except ViewerUnavailable as error:
            self.get_logger().error(f'{parameters.VIEWER}: {error}')
            return None

    def _on_pause(self, request, response):
        """~/pause: the runtime's answer, or while starting the `paused` parameter set to
        `request.data` (the simulation then starts so)."""
        if self.runtime is not None:
            return self._answer(self.runtime.pause(request.data), response)
        if self._startup is None:
            return self._answer(self._no_simulation('pause'), response)
        self.set_parameters([Parameter(parameters.PAUSED, value=bool(request.data))])
        return self._answer(self._startup.pause_answer(request.data), response)

    def _on_trigger(self, name, response):
        """~/reset, ~/step, ~/reset_terrain: the runtime's answer, refused while starting."""
        if self.runtime is not None:
            return self._answer(getattr(self.runtime, name)(), response)
        if self._startup is None:
            return self._answer(self._no_simulation(name), response)
        return self._answer(self._startup.refusal(name), response)

    @staticmethod
    def _no_simulation(service):
        """A service's answer after a description from the topic failed to build."""
        return ServiceResult(False, f'{service}: no simulation; waiting for a robot on '
                                    f'{topics.ROBOT_DESCRIPTION} that builds')

    def _answer(self, result, response):
        response.success, response.message = result.success, result.message
        if self.runtime is not None:
            self._sync_paused()
        return response

    def _sync_paused(self):
        """Keep the `paused` parameter equal to the runtime's state (services, divergence)."""
        if self.get_parameter(parameters.PAUSED).value != self.runtime.paused:
            self.set_parameters([Parameter(parameters.PAUSED, value=self.runtime.paused)])

    def _check_parameters(self, changes):
        """Accept or refuse the changes (the reason says why); while starting they are
        checked as the running simulation would check them, and kept for its start. A
        parameter being declared (rclpy calls this then too) is checked where it is."""
        check = (parameters.parameter_problem if self.runtime is None
                 else self.runtime.parameter_problem)
        for change in changes:
            if change.value == [] and self._value(change.name) is None:
                continue  # (`_declare` giving a string list without a value the empty one)
            if change.name in parameters.SPECS and self.has_parameter(change.name):
                problem = check(change.name, change.value)
                if problem:
                    return SetParametersResult(successful=False, reason=problem)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, changes):
        if self.runtime is None:  # (the simulation starts with the parameters' values)
            return
        for change in changes:
            if change.value is None:  # (declared without a value: joint_gains unset)
                continue
            if change.name in parameters.SPECS and parameters.SPECS[change.name].dynamic:
                self.runtime.set_parameter(change.name, change.value)
                if change.name == parameters.REAL_TIME_FACTOR:
                    self._timer.timer_period_ns = int(self.runtime.tick_period * 1e9)


class _GoalListener:
    """The runtime's side of an rclpy goal handle: feedback and the end go to the client;
    `result` is done with the Result message once the goal has ended."""

    def __init__(self, factory, goal_handle):
        self._factory, self._handle = factory, goal_handle
        self.result = Future()

    def publish_feedback(self, feedback):
        self._handle.publish_feedback(follow_messages.feedback_message(self._factory, feedback))

    def cancel_requested(self):
        return self._handle.is_cancel_requested

    def finish(self, outcome):
        end = {GoalState.SUCCEEDED: self._handle.succeed, GoalState.ABORTED: self._handle.abort,
               GoalState.CANCELED: self._handle.canceled}[outcome.state]
        end()
        self.result.set_result(follow_messages.result_message(self._factory, outcome))


def main(args=None):
    """Entry point of `ros2 run rft_sim_ros sim`; returns the exit status."""
    return run_node(SimNode, NODE_NAME, (ValueError,), args,
                    late_errors=(StartFailed,))


if __name__ == '__main__':
    sys.exit(main())
