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
"""
import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException

from ..interrupts import interrupts_never_lost, release_quietly


@interrupts_never_lost()
def run_node(make_node, name, startup_errors=(), args=None):
    """Spin the node `make_node()` until Ctrl-C, SIGTERM or shutdown; returns the exit status.

    An exception of `startup_errors` (or a ParameterException: a parameter of the wrong
    type) raised while building the node is logged as fatal under `name`, without a
    traceback, and gives status 1: it means a bad scene or parameter, which the message says.
    A signal at any point (start-up included) gives status 0 (see module docstring).
    """
    rclpy.init(args=args)
    try:
        try:
            node = make_node()
        except (ParameterException, *startup_errors) as error:
            if not rclpy.ok():  # a signal shut the context down while building
                return 0
            rclpy.logging.get_logger(name).fatal(f'cannot start: {error}')
            return 1
        try:
            rclpy.spin(node)
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
