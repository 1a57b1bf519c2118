"""The shared life of an rclpy executable: init, build the node, spin, shut down."""
import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException


def run_node(make_node, name, startup_errors=(), args=None):
    """Spin the node `make_node()` until Ctrl-C or shutdown; returns the exit status.

    An exception of `startup_errors` (or a ParameterException: a parameter of the wrong
    type) raised while building the node is logged as fatal under `name`, without a
    traceback, and gives status 1: it means a bad scene or parameter, which the message says.
    """
    rclpy.init(args=args)
    try:
        try:
            node = make_node()
        except (ParameterException, *startup_errors) as error:
            rclpy.logging.get_logger(name).fatal(f'cannot start: {error}')
            return 1
        try:
            rclpy.spin(node)
        except (KeyboardInterrupt, ExternalShutdownException):
            pass
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown()
    return 0
