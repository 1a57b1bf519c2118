"""Test configuration: reproducible property tests, a plate cache of the tests' own, numba's
kernels rather than prebuilt ones (RFT_SIM_PREBUILT=0; `test_prebuilt` tests those), and
SIGINT as a terminal's foreground job has it (`ctrl_c_raises`), and the rclpy tests' ROS
session (`ros`: test_node_rclpy.Ros, only where rclpy is installed).

Hypothesis draws the same examples on every run (derandomize), so CI is deterministic; set
HYPOTHESIS_PROFILE=explore for a long randomised search when changing the force law.
"""
import os
import signal
import tempfile

import pytest
from hypothesis import settings

# plates made by the tests are cached in a folder of their own, not the user's cache
os.environ['XDG_CACHE_HOME'] = tempfile.mkdtemp(prefix='rft-sim-test-cache-')
# the tests run numba's kernels (and test their cache), whether or not `rft-sim warmup` built
# the prebuilt ones in this checkout; test_prebuilt builds and tests those in its own folder.
# (RFT_SIM_PREBUILT=1 in the environment runs them on the prebuilt kernels instead: then the
# tests of a cold start's compile do not hold.)
os.environ.setdefault('RFT_SIM_PREBUILT', '0')

settings.register_profile('default', max_examples=200, derandomize=True, deadline=None)
settings.register_profile('explore', max_examples=5000, deadline=None)
settings.load_profile(os.environ.get('HYPOTHESIS_PROFILE', 'default'))


@pytest.fixture
def ctrl_c_raises():
    """SIGINT as in a terminal's foreground job: a KeyboardInterrupt (this test run may be a
    background job, whose SIGINT is ignored)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.fixture(autouse=True, scope='session')
def mujoco_log_of_the_test_run(tmp_path_factory):
    """MuJoCo's warnings from simulations the tests step themselves (some diverge on
    purpose) go to a file of the test run's, not to MUJOCO_LOG.TXT in the working folder."""
    from rft_sim_ros.sim.runner import mujoco_log
    with mujoco_log(tmp_path_factory.mktemp('mujoco') / 'mujoco.log'):
        yield


@pytest.fixture
def ros():
    """A ROS session of the rclpy tests (`test_node_rclpy.Ros`: rclpy on this test's DDS
    domain, a probe node and an executor), closed after the test."""
    from test_node_rclpy import Ros
    session = Ros()
    yield session
    session.close()
