"""Messages built from a SimState, checked field by field against the ROS 2 Jazzy definitions
(rosbags typestore) and round-tripped through CDR."""
import subprocess
import sys
from decimal import Decimal

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rft_sim_ros.ros import messages, topics
from rft_sim_ros.ros.factory import (MessageFactory, RclpyFactory, RosbagsFactory,
                                     jazzy_typestore)
from rft_sim_ros.stamps import ros_time_to_seconds, seconds_to_ns, split_ns
from rft_sim_ros.sim.state import ActivePlates, LegWrench, SimState
from rft_sim_ros.units import zeta_to_si
from ros_test_support import make_state, make_terrain_update, messages_equal, rotation_from_xyzw

TS = jazzy_typestore()
FACTORY = RosbagsFactory(TS)


def roundtrip(msg):
    """Serialise with the Jazzy CDR definitions and read back."""
    return TS.deserialize_cdr(TS.serialize_cdr(msg, msg.__msgtype__), msg.__msgtype__)


def stamp_ns(time_msg):
    return time_msg.sec * 1_000_000_000 + time_msg.nanosec


def vec(v):
    return np.array([v.x, v.y, v.z])


# --- stamps ---------------------------------------------------------------------------------


@pytest.mark.parametrize('backend', [RosbagsFactory, RclpyFactory])
def test_both_backends_implement_the_factory_interface(backend):
    """messages.py uses only MessageFactory's methods; each backend has all of them with the
    same parameters."""
    import inspect
    for name, method in inspect.getmembers(MessageFactory, inspect.isfunction):
        if name.startswith('_'):
            continue
        implemented = getattr(backend, name, None)
        assert callable(implemented), f'{backend.__name__} lacks {name}'
        assert (list(inspect.signature(implemented).parameters)
                == list(inspect.signature(method).parameters)), name

@pytest.mark.parametrize('t, sec, nanosec', [
    (0.0, 0, 0),
    (1.5, 1, 500_000_000),
    (0.1, 0, 100_000_000),
    (12.3456789012, 12, 345_678_901),
    (1.9999999996, 2, 0),               # rounds up across the second
    (0.0009765625, 0, 976_563),         # exact binary tie 976562.5 ns: half away from zero
    (3.0000000004, 3, 0),
    (-0.25, -1, 750_000_000),           # nanosec stays in [0, 1e9)
])
def test_stamp_rounds_to_nearest_nanosecond(t, sec, nanosec):
    msg = messages.stamp(FACTORY, t)
    assert (msg.sec, msg.nanosec) == (sec, nanosec)
    assert messages_equal(roundtrip(msg), msg)


@settings(max_examples=300)
@given(st.floats(min_value=0.0, max_value=1.0e6))
def test_stamp_is_within_half_a_nanosecond(t):
    msg = messages.stamp(FACTORY, t)
    assert 0 <= msg.nanosec < 1_000_000_000
    assert abs(Decimal(stamp_ns(msg)) - Decimal(t) * 10**9) <= Decimal('0.5')
    assert abs(ros_time_to_seconds(msg) - t) <= 1e-9 * max(1.0, t)


@settings(max_examples=500)
@given(st.floats(allow_nan=False, allow_infinity=False))
def test_nanoseconds_are_the_exact_value_rounded_half_away_from_zero(t):
    """Any finite float, tiny, huge or negative: the decimal rounding of its exact value."""
    from decimal import ROUND_HALF_UP, localcontext
    with localcontext() as context:
        context.prec = 400  # every digit of any double times 1e9
        exact = Decimal(t).scaleb(9).to_integral_value(rounding=ROUND_HALF_UP)
    assert seconds_to_ns(t) == int(exact)


@pytest.mark.parametrize('bad', [float('nan'), float('inf'), -float('inf')])
def test_stamp_rejects_non_finite_time(bad):
    with pytest.raises(ValueError, match='finite'):
        seconds_to_ns(bad)


def test_split_ns_keeps_nanosec_in_range():
    assert split_ns(-1) == (-1, 999_999_999)
    assert split_ns(2_000_000_001) == (2, 1)


# --- individual messages --------------------------------------------------------------------

def test_clock_is_sim_time():
    state = make_state(time=7.000000123)
    msg = messages.clock_message(FACTORY, state)
    assert msg.__msgtype__ == topics.CLOCK_TYPE
    assert (msg.clock.sec, msg.clock.nanosec) == (7, 123)


def test_joint_state_fields():
    state = make_state()
    msg = messages.joint_state_message(FACTORY, state)
    assert msg.__msgtype__ == topics.JOINT_STATE_TYPE
    assert msg.header.frame_id == ''
    assert stamp_ns(msg.header.stamp) == seconds_to_ns(state.time)
    assert msg.name == list(state.joint_names)
    np.testing.assert_array_equal(msg.position, state.joint_positions)
    np.testing.assert_array_equal(msg.velocity, state.joint_velocities)
    np.testing.assert_array_equal(msg.effort, state.joint_efforts)


def test_odometry_frames_pose_and_covariance():
    state = make_state()
    msg = messages.odometry_message(FACTORY, state)
    assert msg.__msgtype__ == topics.ODOMETRY_TYPE
    assert (msg.header.frame_id, msg.child_frame_id) == ('odom', 'trunk')
    assert stamp_ns(msg.header.stamp) == seconds_to_ns(state.time)
    np.testing.assert_array_equal(vec(msg.pose.pose.position), state.base_position)
    q = msg.pose.pose.orientation
    w, x, y, z = state.base_quaternion_wxyz
    assert (q.x, q.y, q.z, q.w) == (x, y, z, w)
    for covariance in (msg.pose.covariance, msg.twist.covariance):
        assert covariance.shape == (36,)
        assert not covariance.any()          # exact ground truth, and not "unknown" (-1)


def test_odometry_twist_is_in_the_child_frame():
    # The state carries base velocities in base_link; rotating the published twist by the
    # published orientation must give the world velocity, which differs from the twist.
    state = make_state()
    msg = messages.odometry_message(FACTORY, state)
    q = msg.pose.pose.orientation
    rotation = rotation_from_xyzw(q.x, q.y, q.z, q.w)
    linear, angular = vec(msg.twist.twist.linear), vec(msg.twist.twist.angular)
    np.testing.assert_array_equal(linear, state.base_linear_velocity)
    np.testing.assert_array_equal(angular, state.base_angular_velocity)
    world_linear = rotation @ linear
    assert not np.allclose(world_linear, linear)
    np.testing.assert_allclose(rotation.T @ world_linear, state.base_linear_velocity)


def test_quaternion_order_matches_rotation():
    # 90 deg about z: ROS (x, y, z, w) = (0, 0, s, c); the x axis must map to +y.
    c = s = np.sqrt(0.5)
    state = make_state()
    state = SimState(**{**state.__dict__, 'base_quaternion_wxyz': np.array([c, 0.0, 0.0, s])})
    q = messages.odometry_message(FACTORY, state).pose.pose.orientation
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, s, c)
    np.testing.assert_allclose(rotation_from_xyzw(q.x, q.y, q.z, q.w) @ [1, 0, 0], [0, 1, 0],
                               atol=1e-12)


def test_tf_has_base_and_one_world_aligned_frame_per_leg():
    state = make_state(legs=('L1', 'R2', 'L3'))
    msg = messages.tf_message(FACTORY, state)
    assert msg.__msgtype__ == topics.TF_TYPE
    assert len(msg.transforms) == 1 + len(state.legs)
    base = msg.transforms[0]
    assert (base.header.frame_id, base.child_frame_id) == ('odom', 'trunk')
    odom = messages.odometry_message(FACTORY, state)
    np.testing.assert_array_equal(vec(base.transform.translation), vec(odom.pose.pose.position))
    assert messages_equal(base.transform.rotation, odom.pose.pose.orientation)
    for leg, transform in zip(state.legs, msg.transforms[1:]):
        assert transform.header.frame_id == 'odom'
        assert transform.child_frame_id == f'rft/{leg.name}'
        np.testing.assert_array_equal(vec(transform.transform.translation), leg.point)
        r = transform.transform.rotation
        assert (r.x, r.y, r.z, r.w) == (0.0, 0.0, 0.0, 1.0)
    assert {stamp_ns(t.header.stamp) for t in msg.transforms} == {seconds_to_ns(state.time)}


def test_leg_wrench_in_leg_frame_with_world_axes():
    state = make_state()
    tf_children = {t.child_frame_id for t in messages.tf_message(FACTORY, state).transforms}
    for leg in state.legs:
        msg = messages.leg_wrench_message(FACTORY, state, leg)
        assert msg.__msgtype__ == topics.WRENCH_TYPE
        assert msg.header.frame_id == topics.leg_frame_id(leg.name) == f'rft/{leg.name}'
        assert msg.header.frame_id in tf_children
        assert stamp_ns(msg.header.stamp) == seconds_to_ns(state.time)
        np.testing.assert_array_equal(vec(msg.wrench.force), leg.force)
        np.testing.assert_array_equal(vec(msg.wrench.torque), leg.torque)


def test_plates_marker_points_and_stress_colours():
    zeta = 2.0
    full = zeta_to_si(zeta) * messages.PLATE_STRESS_FULL_SCALE_DEPTH_M   # Pa
    areas = np.array([1e-4, 2e-4, 1e-4])
    stress = np.array([0.0, 0.5 * full, 3.0 * full])
    forces = np.zeros((3, 3))
    forces[:, 2] = stress * areas
    positions = np.array([[0.1, 0.2, -0.01], [0.0, 0.0, -0.02], [-0.3, 0.1, -0.005]])
    state = SimState(**{**make_state().__dict__, 'zeta': zeta,
                        'active_plates': ActivePlates(positions, forces, areas)})
    array_msg = messages.plates_message(FACTORY, state)
    assert array_msg.__msgtype__ == topics.MARKER_ARRAY_TYPE
    (marker,) = array_msg.markers
    marker_type = TS.types['visualization_msgs/msg/Marker']
    assert marker.type == marker_type.SPHERE_LIST
    assert marker.action == marker_type.ADD
    assert (marker.header.frame_id, marker.ns, marker.id) == ('odom', 'rft_plates', 0)
    assert stamp_ns(marker.header.stamp) == seconds_to_ns(state.time)
    np.testing.assert_array_equal([[p.x, p.y, p.z] for p in marker.points], positions)
    colours = np.array([[c.r, c.g, c.b, c.a] for c in marker.colors])
    np.testing.assert_allclose(colours, [[0, 0, 1, 1], [0.5, 0, 0.5, 1], [1, 0, 0, 1]],
                               atol=1e-7)
    expected_size = np.sqrt(areas.mean())
    assert (marker.scale.x, marker.scale.y, marker.scale.z) == (expected_size,) * 3
    assert marker.pose.orientation.w == 1.0


def test_plates_marker_deleted_when_no_plate_is_active():
    empty = ActivePlates(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    state = SimState(**{**make_state().__dict__, 'active_plates': empty, 'plates_active': 0})
    (marker,) = roundtrip(messages.plates_message(FACTORY, state)).markers
    assert marker.action == TS.types['visualization_msgs/msg/Marker'].DELETE
    assert (marker.points, marker.colors) == ([], [])


def diagnostic_values(msg):
    (status,) = msg.status
    return status, {kv.key: kv.value for kv in status.values}


def test_diagnostics_ok():
    state = make_state()
    run = messages.RunStatus(scene='hexapod', real_time_factor=14.5,
                             commands_rejected={'unknown_joint': 3, 'not_finite': 1},
                             kernels='prebuilt kernels: in use')
    msg = messages.diagnostics_message(FACTORY, state, run)
    assert msg.__msgtype__ == topics.DIAGNOSTICS_TYPE
    assert stamp_ns(msg.header.stamp) == seconds_to_ns(state.time)
    status, values = diagnostic_values(msg)
    assert status.level == TS.types['diagnostic_msgs/msg/DiagnosticStatus'].OK
    assert status.hardware_id == 'hexapod'
    assert float(values['sim_time_s']) == state.time
    assert float(values['zeta_n_per_cm3']) == state.zeta
    assert float(values['real_time_factor']) == 14.5
    assert int(values['plates_active']) == state.plates_active
    assert values['stable'] == 'true'
    assert status.message == 'running' and values['paused'] == 'false'
    assert int(values['commands_rejected']) == 4
    assert int(values['commands_rejected.unknown_joint']) == 3
    assert int(values['commands_rejected.not_finite']) == 1
    assert values['kernels'] == 'prebuilt kernels: in use'


def test_diagnostics_error_when_diverged():
    run = messages.RunStatus(scene='drop', real_time_factor=float('nan'), stable=False,
                             problem='NaN in qpos at t = 0.25 s')
    status, values = diagnostic_values(messages.diagnostics_message(FACTORY, make_state(), run))
    assert status.level == TS.types['diagnostic_msgs/msg/DiagnosticStatus'].ERROR
    assert status.message == 'NaN in qpos at t = 0.25 s'
    assert values['stable'] == 'false'
    assert values['commands_rejected'] == '0'
    assert np.isnan(float(values['real_time_factor']))
    assert 'kernels' not in values  # (not said)


def test_diagnostics_say_paused():
    run = messages.RunStatus(scene='drop', real_time_factor=0.0, paused=True)
    status, values = diagnostic_values(messages.diagnostics_message(FACTORY, make_state(), run))
    assert status.level == TS.types['diagnostic_msgs/msg/DiagnosticStatus'].OK
    assert status.message == 'paused' and values['paused'] == 'true'


# --- the publishing cycle -------------------------------------------------------------------

@pytest.mark.parametrize('plates', [True, False])
def test_state_messages_match_the_topic_table(plates):
    state = make_state(legs=('L1', 'L2', 'R1'))
    published = messages.state_messages(FACTORY, state, plates=plates)
    table = topics.published_topics([leg.name for leg in state.legs], plates=plates)
    assert [t for t, _ in published] == [t for t in table if t != topics.DIAGNOSTICS]
    for topic, msg in published:
        assert msg.__msgtype__ == table[topic]


def test_state_messages_without_plate_data_skip_the_marker():
    state = make_state(plates=None)
    published = dict(messages.state_messages(FACTORY, state, plates=True))
    assert topics.PLATES not in published and topics.CLOCK in published


@pytest.mark.parametrize('clear', [True, False])
def test_a_terrain_publication_is_a_cloud_and_one_marker_array(clear):
    """The types of the topic table; every marker of the publication in one MarkerArray, in
    the order RViz applies them (DELETEALL first when sent whole, then by tile)."""
    published = messages.terrain_messages(FACTORY, make_terrain_update(clear))
    table = topics.published_topics([], plates=False, terrain=True)
    assert [topic for topic, _ in published] == [topics.TERRAIN, topics.TERRAIN_MARKER]
    for topic, msg in published:
        assert msg.__msgtype__ == table[topic]
    markers = roundtrip(published[1][1]).markers
    assert [(m.action, m.id) for m in markers] == ([(3, 0)] if clear else []) + [(0, 3), (2, 7)]
    assert len(markers[-2].points) == 2 and not markers[-1].points


finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)
leg_name = st.from_regex(r'[A-Za-z][A-Za-z0-9_]{0,8}', fullmatch=True)


@st.composite
def sim_states(draw):
    n_joints = draw(st.integers(0, 6))
    arrays = st.lists(finite, min_size=n_joints, max_size=n_joints).map(np.array)
    vec3 = st.lists(finite, min_size=3, max_size=3).map(np.array)
    quat = st.lists(st.floats(-1, 1), min_size=4, max_size=4).filter(
        lambda q: np.linalg.norm(q) > 0.1).map(lambda q: np.array(q) / np.linalg.norm(q))
    legs = draw(st.lists(leg_name, max_size=4, unique=True))
    n_plates = draw(st.integers(0, 5))
    plates = ActivePlates(
        positions=np.array(draw(st.lists(vec3, min_size=n_plates, max_size=n_plates))
                           ).reshape(-1, 3),
        forces=np.array(draw(st.lists(vec3, min_size=n_plates, max_size=n_plates))
                        ).reshape(-1, 3),
        areas=np.array(draw(st.lists(st.floats(1e-8, 1e-2), min_size=n_plates,
                                     max_size=n_plates))))
    return SimState(
        time=draw(st.floats(0, 1e6)),
        joint_names=tuple(draw(st.lists(st.text(max_size=10), min_size=n_joints,
                                        max_size=n_joints))),
        joint_positions=draw(arrays), joint_velocities=draw(arrays),
        joint_efforts=draw(arrays), base_frame=draw(st.text(min_size=1, max_size=20)),
        base_position=draw(vec3), base_quaternion_wxyz=draw(quat),
        base_linear_velocity=draw(vec3), base_angular_velocity=draw(vec3),
        legs=tuple(LegWrench(name, draw(vec3), draw(vec3), draw(vec3)) for name in legs),
        zeta=draw(st.floats(0.1, 100)), plates_active=n_plates, active_plates=plates)


@settings(max_examples=60, deadline=None)
@given(sim_states())
def test_every_message_round_trips_through_jazzy_cdr(state):
    run = messages.RunStatus(scene='s', real_time_factor=2.0, commands_rejected={'empty': 1})
    published = messages.state_messages(FACTORY, state, plates=True)
    published.append((topics.DIAGNOSTICS, messages.diagnostics_message(FACTORY, state, run)))
    assert len(published) == 6 + len(state.legs)
    for _, msg in published:
        assert messages_equal(roundtrip(msg), msg)


# --- names, factory, ROS isolation ----------------------------------------------------------

@pytest.mark.parametrize('bad', ['', '1leg', 'leg/1', 'leg-1', 'leg 1'])
def test_leg_names_must_be_valid_ros_name_tokens(bad):
    with pytest.raises(ValueError, match='leg name'):
        topics.leg_wrench_topic(bad)


def test_duplicate_leg_names_are_refused():
    with pytest.raises(ValueError, match='twice'):
        topics.published_topics(['L1', 'L1'], plates=False)


def test_fixed_size_array_checks_its_size():
    with pytest.raises(ValueError, match='36'):
        FACTORY.float64_array(np.zeros(35), 36)


def test_message_code_imports_no_ros():
    code = ('import sys; import rft_sim_ros.ros.messages, rft_sim_ros.ros.bag, '
            'rft_sim_ros.ros.inbound, rft_sim_ros.control.commands; '
            'bad = [m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "std_msgs", "sensor_msgs", "rosgraph_msgs")]; print(bad); '
            'sys.exit(1 if bad else 0)')
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


def test_rclpy_backend_matches_rosbags_backend():
    """Where ROS 2 is installed: the rclpy messages serialise to what rosbags builds."""
    pytest.importorskip('rclpy', reason='ROS 2 (rclpy) is not installed here')
    from rclpy.serialization import serialize_message
    state = make_state()
    run = messages.RunStatus(scene='s', real_time_factor=2.0, stable=False, problem='x')
    rclpy_factory = RclpyFactory()
    built = [messages.state_messages(f, state, plates=True)
             + [(topics.DIAGNOSTICS, messages.diagnostics_message(f, state, run))]
             + messages.terrain_messages(f, make_terrain_update(clear=True))
             for f in (rclpy_factory, FACTORY)]
    for (topic, ros_msg), (_, reference) in zip(*built):
        decoded = TS.deserialize_cdr(serialize_message(ros_msg), reference.__msgtype__)
        assert messages_equal(decoded, reference), topic
