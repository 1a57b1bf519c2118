"""simulation_interfaces' services answered from the runtime (rft_sim_ros.ros.
simulation_services), ROS-free (rosbags has no simulation_interfaces types): features said
truthfully, reset, step while paused only, get / set state with the package's codes."""
import pytest

from rft_sim_ros.ros import simulation_services as si
from rft_sim_ros.scenes.config import load_scene
from ros_test_support import SERVO_RIG, Harness


@pytest.fixture
def rig():
    h = Harness(load_scene(SERVO_RIG))
    h.runtime.tick()
    return h, si.SimulationServices(h.runtime)


def test_features_list_what_is_served_and_not_time_reset():
    features, formats, info = si.SimulationServices.features()
    assert set(features) == {20, 22, 24, 25, 26, 31, 32, 33}
    assert si.SIMULATION_RESET_TIME not in features and formats == []
    assert 'publish period' in info


def test_play_pause_stop_and_the_codes_of_each_transition(rig):
    h, services = rig
    assert services.state().state == si.STATE_PLAYING
    assert services.set_state(si.STATE_PLAYING).result == si.ALREADY_IN_TARGET_STATE
    assert services.set_state(si.STATE_PAUSED).result == si.RESULT_OK and h.runtime.paused
    assert services.state().state == si.STATE_PAUSED
    h.run(0.2)
    assert h.sim.time == 0.0  # paused: no time passes
    assert services.set_state(si.STATE_PLAYING).result == si.RESULT_OK
    h.run(0.1)
    assert h.sim.time == pytest.approx(0.1)
    stop = services.set_state(si.STATE_STOPPED)
    assert stop.result == si.RESULT_OK and h.runtime.paused
    assert services.state().state == si.STATE_STOPPED
    assert services.set_state(si.STATE_QUITTING).result == si.RESULT_FEATURE_UNSUPPORTED
    assert services.step(2).result == si.RESULT_OK  # stepping leaves the stopped state
    assert services.state().state == si.STATE_PAUSED


def test_stopped_is_paused_at_the_initial_state_by_any_reset_until_it_moves_on(rig):
    h, services = rig
    h.run(0.1)
    services.reset(si.SCOPE_STATE)  # playing: a reset keeps playing
    assert services.state().state == si.STATE_PLAYING
    services.set_state(si.STATE_PAUSED)
    assert services.state().state == si.STATE_PAUSED
    assert services.reset(si.SCOPE_ALL).result == si.RESULT_OK  # paused and reset: stopped
    assert services.state().state == si.STATE_STOPPED
    assert services.set_state(si.STATE_STOPPED).result == si.ALREADY_IN_TARGET_STATE
    assert services.set_state(si.STATE_PAUSED).result == si.RESULT_OK  # no time passes
    assert services.state().state == si.STATE_PAUSED and h.runtime.paused
    h.runtime.reset()  # the node's own ~/reset too
    assert services.state().state == si.STATE_STOPPED
    assert services.set_state(si.STATE_PLAYING).result == si.RESULT_OK
    assert services.state().state == si.STATE_PLAYING
    started_paused = Harness(load_scene(SERVO_RIG), paused=True)
    assert si.SimulationServices(started_paused.runtime).state().state == si.STATE_STOPPED


def test_step_needs_a_pause_and_advances_whole_publish_periods(rig):
    h, services = rig
    refused = services.step(1)
    assert refused.result == si.RESULT_OPERATION_FAILED and 'pause' in refused.message
    services.set_state(si.STATE_PAUSED)
    published = len(h.sink.states)
    stepped = services.step(3)
    assert stepped.result == si.RESULT_OK
    assert stepped.message.startswith('3 steps: 0.03 s to sim time'), stepped.message
    assert h.sim.time == pytest.approx(3 * h.runtime.publish_period)
    assert len(h.sink.states) == published + 3
    assert services.step(0).result == si.RESULT_OPERATION_FAILED


def test_simulate_steps_gives_feedback_after_each_step(rig):
    h, services = rig
    services.set_state(si.STATE_PAUSED)
    feedback = []
    done = services.step(3, lambda completed, remaining: feedback.append(
        (completed, remaining, round(h.sim.time / h.runtime.publish_period))))
    assert done.result == si.RESULT_OK
    assert feedback == [(1, 2, 1), (2, 1, 2), (3, 0, 3)]


def test_reset_restores_the_state_and_says_time_runs_on(rig):
    h, services = rig
    h.sim.commands.set_positions([0.5, -0.5], h.sim.time)
    h.run(0.3)
    moved = h.sim.data.joint('hip').qpos[0]
    assert moved == pytest.approx(0.5, abs=0.05)
    before = h.sim.time
    answer = services.reset(si.SCOPE_DEFAULT)
    assert answer.result == si.RESULT_OK and 'keeps running forward' in answer.message
    assert h.sim.data.joint('hip').qpos[0] == pytest.approx(0.0, abs=1e-9)
    assert h.sim.time == pytest.approx(before)
    assert services.reset(si.SCOPE_TIME).result == si.RESULT_FEATURE_UNSUPPORTED
    h.sim.commands.set_positions([0.5, -0.5], h.sim.time)
    h.run(0.3)
    spawned = services.reset(si.SCOPE_SPAWNED)  # (nothing spawned: nothing to do)
    assert spawned.result == si.RESULT_OK and 'nothing removed' in spawned.message
    assert h.sim.data.joint('hip').qpos[0] == pytest.approx(0.5, abs=0.05)
    assert services.reset(8).result == si.RESULT_FEATURE_UNSUPPORTED
    assert services.reset(si.SCOPE_STATE).message.startswith('reset at sim time')
