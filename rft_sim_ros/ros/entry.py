"""The shared life of an rclpy executable: init, build the node, spin, shut down.

Shutdown on a signal: rclpy.init installs handlers for SIGINT and SIGTERM that shut the
context down from a helper thread while the main thread may be anywhere, often inside a
callback that is publishing. SIGINT also raises KeyboardInterrupt in the main thread. So a
signal surfaces as KeyboardInterrupt, as ExternalShutdownException, or as whatever error a
ROS call inside a callback (a publish, a parameter update) raises once its context is gone
(RCLError "publisher's context is invalid"). All of these are a requested shutdown, not a
failure: the executable exits with status 0 and without a traceback (`release_quietly`). An
error raised while the context is still valid is a real failure and propagates. A
KeyboardInterrupt that lands where it cannot be raised (a callback of llvmlite's while numba
compiles the kernels of a first start) is not printed but delivered again
(`interrupts_never_lost`).

Command-line ROS arguments that rcl cannot read (a `-p` value that is not YAML, such as
`sand_bodies:=*_foot`) are refused in one fatal line that says why and how to quote
(`parameters.arguments_problem`), with status 1.
"""
import rclpy
import rclpy.logging
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.utilities import remove_ros_args

from ..interrupts import interrupts_never_lost, release_quietly
from .parameters import arguments_problem


@interrupts_never_lost()
def run_node(make_node, name, startup_errors=(), args=None, late_errors=()):
    """Spin the node `make_node()` until Ctrl-C, SIGTERM or shutdown; returns the exit status.

    ROS arguments rcl cannot read (`args`, default sys.argv), or an exception of
    `startup_errors` (or a ParameterException: a parameter of the wrong type) raised while
    building the node, or of `late_errors` raised while it spins (a start-up that ends in
    the executor: `ros.startup.StartFailed`), are logged as fatal under `name`, without a
    traceback, and give status 1: they mean a bad argument, scene or parameter, which the
    message says. A signal at any point (start-up included) gives status 0 (see module
    docstring).
    """
    logger = rclpy.logging.get_logger(name)
    try:
        remove_ros_args(args)  # rcl reads them as rclpy.init does, without logging an error
    except rclpy_implementation.RCLError as error:
        logger.fatal(f'cannot start: {arguments_problem(str(error))}')
        return 1
    rclpy.init(args=args)
    try:
        try:
            node = make_node()
        except (ParameterException, *startup_errors) as error:
            if not rclpy.ok():  # a signal shut the context down while building
                return 0
            logger.fatal(f'cannot start: {error}')
            return 1
        try:
            rclpy.spin(node)
        except late_errors as error:
            if not rclpy.ok():
                return 0
            logger.fatal(f'cannot start: {error}')
            return 1
        finally:
            node.destroy_node()
    except (KeyboardInterrupt, ExternalShutdownException) as stop:
        release_quietly(stop)
    except Exception:
        if rclpy.ok():  # the context is valid: a real failure
            raise
    finally:
        rclpy.try_shutdown()
    return 0
