"""external: no built-in behaviour; the model's position servos take commands from outside.

For scenes driven only through `Simulation.commands` (the ROS node's command topics, or a
script): the initial state is the model's, there is no control of its own and no metrics.
"""
from . import BaseScenario


class Scenario(BaseScenario):
    """All hooks are BaseScenario's no-ops."""
