"""The rft_sim node's simulation_interfaces services and SimulateSteps action, in-process over
rclpy with the package's own messages: features, pause through SetSimulationState, the
state read back, StepSimulation and SimulateSteps (feedback per step) advancing whole
publish periods, a reset that keeps sim time.

Runs where ROS 2 Jazzy and its simulation_interfaces package are installed; skipped with the
reason everywhere else.
"""
import pytest

rclpy = pytest.importorskip('rclpy', reason='ROS 2 Jazzy (rclpy) is not installed here')
pytest.importorskip('simulation_interfaces.srv',
                    reason='ROS 2 package simulation_interfaces is not installed here')

from rclpy.action import ActionClient  # noqa: E402
from simulation_interfaces import action, msg, srv  # noqa: E402

from test_node_rclpy import start_sim  # noqa: E402

pytestmark = pytest.mark.ros


def test_services_and_the_simulate_steps_action_answer_with_the_package_codes(ros):
    sim = start_sim(ros)
    probe = ros.probe
    clients = {name: probe.create_client(kind, f'/{name}') for name, kind in (
        ('get_simulator_features', srv.GetSimulatorFeatures),
        ('set_simulation_state', srv.SetSimulationState),
        ('get_simulation_state', srv.GetSimulationState),
        ('step_simulation', srv.StepSimulation),
        ('reset_simulation', srv.ResetSimulation))}
    features = ros.call(clients['get_simulator_features'], srv.GetSimulatorFeatures.Request())
    assert msg.SimulatorFeatures.STEP_SIMULATION_ACTION in features.features.features
    assert msg.SimulatorFeatures.SIMULATION_RESET_TIME not in features.features.features

    refused = ros.call(clients['step_simulation'], srv.StepSimulation.Request(steps=2))
    assert refused.result.result == msg.Result.RESULT_OPERATION_FAILED  # playing
    paused = ros.call(clients['set_simulation_state'], srv.SetSimulationState.Request(
        state=msg.SimulationState(state=msg.SimulationState.STATE_PAUSED)))
    assert paused.result.result == msg.Result.RESULT_OK
    assert sim.get_parameter('paused').value is True
    state = ros.call(clients['get_simulation_state'], srv.GetSimulationState.Request())
    assert state.state.state == msg.SimulationState.STATE_PAUSED

    period = sim.runtime.publish_period
    start = sim.runtime.sim.time
    stepped = ros.call(clients['step_simulation'], srv.StepSimulation.Request(steps=3))
    assert stepped.result.result == msg.Result.RESULT_OK, stepped.result.error_message
    assert sim.runtime.sim.time == pytest.approx(start + 3 * period)

    steps = ActionClient(probe, action.SimulateSteps, '/simulate_steps')
    assert steps.wait_for_server(timeout_sec=5.0)
    ros.spin_for(2.0)  # (the server's feedback topic matched too: wait_for_server asks services)
    feedback = []
    sent = steps.send_goal_async(action.SimulateSteps.Goal(steps=4),
                                 feedback_callback=lambda f: feedback.append(
                                     (f.feedback.completed_steps, f.feedback.remaining_steps)))
    assert ros.spin_until(sent.done)
    result = sent.result().get_result_async()
    assert ros.spin_until(result.done)
    assert result.result().result.result.result == msg.Result.RESULT_OK
    # feedback after each step, in order (rclpy's client drops a goal's feedback callback
    # when its result comes, so the last feedback, sent just before it, may be missed here;
    # `ros2 action send_goal --feedback` showed all four)
    assert len(feedback) >= 3 and feedback == [(k, 4 - k) for k in range(1, len(feedback) + 1)]
    assert sim.runtime.sim.time == pytest.approx(start + 7 * period)

    before = sim.runtime.sim.time
    reset = ros.call(clients['reset_simulation'], srv.ResetSimulation.Request(
        scope=srv.ResetSimulation.Request.SCOPE_STATE))
    assert reset.result.result == msg.Result.RESULT_OK
    assert sim.runtime.sim.time >= before  # sim time never goes back
