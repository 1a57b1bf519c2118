"""Sensors (rft_sim_ros.sim.sensors) through the publication path (ros.messages, ros.topics,
the bag): an IMU reads +g at rest and the base's orientation and angular velocity while
walking; the hexapod's tripod gait shows alternating stance sets; an MJCF's touch, gyro,
framequat, accelerometer, force and framepos sensors are published, each named after it."""
import mujoco
import numpy as np
import pytest

from rft_sim_ros.ros import messages, topics
from rft_sim_ros.ros.bag import BagWriter, bag_topics, read_messages
from rft_sim_ros.ros.factory import RosbagsFactory, jazzy_typestore
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.sensors import imu_frame
from rft_sim_ros.sim.simulation import Simulation

FACTORY = RosbagsFactory(jazzy_typestore())
G = 9.81


def publish_cycles(sim, seconds):
    """States after each publish period (10 ms) for `seconds` of sim time."""
    states, steps = [], int(round(0.01 / sim.timestep))
    for _ in range(int(round(seconds / 0.01))):
        sim.step(steps)
        states.append(sim.state())
    return states


def rotation(wxyz):
    matrix = np.empty(9)
    mujoco.mju_quat2Mat(matrix, np.asarray(wxyz, dtype=float))
    return matrix.reshape(3, 3)


def test_imu_at_rest_reads_plus_g_up_and_the_base_orientation():
    sim = Simulation(load_scene('quadruped', overrides={'params.gait': 'none',
                                                        'sensors.imu': True}))
    state = publish_cycles(sim, 1.0)[-1]
    message = dict(messages.state_messages(FACTORY, state, plates=False))[topics.IMU]
    assert message.header.frame_id == 'base'
    assert message.header.stamp == messages.stamp(FACTORY, state.time)
    a = message.linear_acceleration
    measured = np.array([a.x, a.y, a.z])
    up = rotation(state.base_quaternion_wxyz).T @ [0.0, 0.0, G]  # +g up, in IMU axes
    assert np.linalg.norm(measured - up) < 0.01 * G, measured
    assert measured[2] == pytest.approx(G, rel=0.01)
    q = message.orientation
    assert [q.w, q.x, q.y, q.z] == state.base_quaternion_wxyz.tolist()
    assert message.linear_acceleration_covariance.tolist() == [0.0] * 9  # exact


def test_no_imu_sample_before_the_first_step_then_one_of_that_step():
    """At the (re)start no step has given the state the sand's forces: its accelerations
    are the pose's forward dynamics without them (the quadruped as set: 22 g), which no IMU
    reads; its first sample comes after the first step, as each reset's."""
    sim = Simulation(load_scene('quadruped', overrides={'params.gait': 'none',
                                                        'sensors.imu': True}))
    for _ in range(2):  # (the start, then a reset)
        first = dict(messages.state_messages(FACTORY, sim.state(), plates=False))
        assert topics.IMU not in first and topics.JOINT_STATES in first
        sim.step(10)
        a = dict(messages.state_messages(FACTORY, sim.state(), plates=False))[
            topics.IMU].linear_acceleration
        assert np.linalg.norm([a.x, a.y, a.z]) < 3 * G
        sim.reset()


def test_imu_while_walking_matches_odom_orientation_and_base_angular_velocity():
    sim = Simulation(load_scene('quadruped', overrides={'params.settle_time': 0.2,
                                                        'sensors.imu': True}))
    turning = 0.0
    for state in publish_cycles(sim, 1.2)[30:]:
        published = dict(messages.state_messages(FACTORY, state, plates=False))
        imu, odom = published[topics.IMU], published[topics.ODOM]
        for axis in 'xyzw':
            assert getattr(imu.orientation, axis) == pytest.approx(
                getattr(odom.pose.pose.orientation, axis), abs=1e-6)
        for axis in 'xyz':
            assert getattr(imu.angular_velocity, axis) == pytest.approx(
                getattr(odom.twist.twist.angular, axis), abs=1e-6)
        turning = max(turning, float(np.linalg.norm(state.base_angular_velocity)))
    assert turning > 0.05  # (the trot rocks the base: the comparison is not of zeros)


def test_imu_noise_and_bias_settings_show_in_readings_and_covariances():
    sim = Simulation(load_scene('quadruped', overrides={
        'params.gait': 'none', 'sensors.imu': True, 'sensors.imu_noise.gyro_std': 0.01,
        'sensors.imu_noise.accel_bias': [0.0, 0.0, 0.5], 'sensors.imu_noise.seed': 3}))
    readings = [s.sensors.imu for s in publish_cycles(sim, 0.5)[20:]]
    gyro = np.array([r.angular_velocity for r in readings])
    assert 0.007 < gyro.std() < 0.013
    assert np.mean([r.linear_acceleration[2] for r in readings]) == pytest.approx(G + 0.5,
                                                                                   rel=0.01)
    assert readings[0].angular_velocity_covariance.tolist() == [1e-4, 0, 0, 0, 1e-4, 0, 0, 0,
                                                                1e-4]


def test_hexapod_tripod_gait_alternates_stance_sets():
    sim = Simulation(load_scene('hexapod', overrides={'params.cycles': 2,
                                                      'rft.plates_per_body': 100,
                                                      'sensors.contacts': True}))
    states = [s for s in publish_cycles(sim, 3.0) if s.time > 1.5]  # walking, ramp done
    contacts = [dict(messages.state_messages(FACTORY, s, plates=False))[topics.FOOT_CONTACTS]
                for s in states]
    legs = list(contacts[0].name)
    assert legs == list(sim.legs)
    stance = np.array([c.position for c in contacts]) == 1.0
    normal = np.array([c.effort for c in contacts])
    np.testing.assert_array_equal(stance, normal > sim.sensors.contact_threshold)
    # the tripods: the legs the gait moves in phase with the first leg, and the others
    gait = sim.scenario.gait
    order = [list(gait.legs.names).index(leg) for leg in legs]
    phases = np.array([gait.phases(s.time) for s in states])[:, order]  # (states, legs)
    in_a = np.isclose(phases[0], phases[0, 0])
    assert in_a.sum() == 3 and (~in_a).sum() == 3, phases[0]
    a_stance_half = phases[:, 0] < gait.stance_fraction
    only_a = stance[:, in_a].all(1) & ~stance[:, ~in_a].any(1)
    only_b = stance[:, ~in_a].all(1) & ~stance[:, in_a].any(1)
    # each leg loaded more in its own tripod's half than in the other's; each tripod alone in
    # stance for a good part of its half (both are in stance around the touchdowns, and the
    # crab's swinging feet, lifted 6 cm, can still drag through sand they sank deeper into),
    # never in the other's
    a_loaded, b_loaded = stance[a_stance_half].mean(0), stance[~a_stance_half].mean(0)
    assert (a_loaded[in_a] > b_loaded[in_a]).all() and (b_loaded[~in_a] > a_loaded[~in_a]).all()
    assert only_a[a_stance_half].mean() > 0.2 and only_b[~a_stance_half].mean() > 0.2
    assert not only_a[~a_stance_half].any() and not only_b[a_stance_half].any()
    pattern = [a for a, b in zip(only_a, only_b) if a or b]
    switches = sum(x != y for x, y in zip(pattern, pattern[1:]))
    assert switches >= 2  # A, B, A ... over the walk's 1.5 cycles
    # every leg swings: its foot unloaded for part of its swing half
    for leg in range(len(legs)):
        swing = phases[:, leg] >= gait.stance_fraction
        assert (~stance[swing, leg]).mean() > 0.3, legs[leg]


SENSOR_BOX = """<mujoco model="sensor_box">
  <option timestep="0.001" gravity="0 0 -9.81"/>
  <worldbody>
    <body name="box" pos="0 0 0.045">
      <freejoint/>
      <geom name="box" type="box" size="0.05 0.05 0.05" mass="1.0"/>
      <site name="imu" pos="0 0 0.02"/>
      <site name="sole" pos="0 0 -0.05" size="0.06 0.06 0.01" type="box"/>
      <body name="tip" pos="0 0 0.06">
        <joint name="tip" type="slide" axis="0 0 1" range="-0.01 0.01"/>
        <geom type="sphere" size="0.01" mass="0.05" contype="0" conaffinity="0"/>
        <site name="tip" pos="0 0 0"/>
      </body>
    </body>
  </worldbody>
  <sensor>
    <touch name="sole_touch" site="sole"/>
    <gyro name="imu_gyro" site="imu"/>
    <framequat name="imu-quat" objtype="site" objname="imu"/>
    <accelerometer name="imu_acc" site="imu"/>
    <force name="tip_force" site="tip"/>
    <framepos name="box_pos" objtype="body" objname="box"/>
  </sensor>
</mujoco>
"""


def test_mjcf_sensors_are_published_and_recorded_by_kind_named_after_each(tmp_path):
    path = tmp_path / 'sensor_box.xml'
    path.write_text(SENSOR_BOX)
    sim = Simulation(load_scene(str(path), overrides={
        'rft.sand_bodies': ['box'], 'rft.plates_per_body': 100, 'sensors.model_sensors': True,
        'sensors.imu': True}))
    model = sim.model
    assert imu_frame(model, sim.model.body('box').id)[2] == 'imu'  # the imu sensors' site
    layout = sim.sensors.layout
    expected = {'/rft/sensors/sole_touch': topics.WRENCH_TYPE,
                '/rft/sensors/imu_gyro': topics.IMU_TYPE,
                '/rft/sensors/imu_quat': topics.IMU_TYPE,  # ('-' is no ROS name character)
                '/rft/sensors/imu_acc': topics.IMU_TYPE,
                '/rft/sensors/tip_force': topics.WRENCH_TYPE,
                '/rft/sensors/box_pos': topics.FLOAT64_ARRAY_TYPE}
    assert topics.sensor_topics(layout) == {topics.IMU: topics.IMU_TYPE, **expected}
    states = publish_cycles(sim, 0.5)
    state = states[-1]
    published = dict(messages.state_messages(FACTORY, state, plates=False))
    box = state.sensors.model_sensors
    values = {s.name: s.values for s in box}
    gyro = published['/rft/sensors/imu_gyro']
    assert gyro.header.frame_id == 'imu'
    assert gyro.orientation_covariance[0] == -1.0 and gyro.linear_acceleration_covariance[0] == -1
    assert gyro.angular_velocity.z == values['imu_gyro'][2]
    quat = published['/rft/sensors/imu_quat']
    assert [quat.orientation.w, quat.orientation.z] == [values['imu-quat'][0],
                                                        values['imu-quat'][3]]
    acc = published['/rft/sensors/imu_acc']
    assert acc.linear_acceleration.z == pytest.approx(G, rel=0.02)  # resting in the sand
    # the box holds the tip up against gravity (MuJoCo's force sensor: parent on child)
    force = published['/rft/sensors/tip_force'].wrench.force
    assert force.z == pytest.approx(0.05 * G, rel=0.01)
    touch = published['/rft/sensors/sole_touch'].wrench.force
    assert touch.z == values['sole_touch'][0] == 0.0  # MuJoCo's touch: rigid contacts only
    assert published['/rft/sensors/box_pos'].data.tolist() == values['box_pos'].tolist()
    assert published['/rft/sensors/box_pos'].layout.dim[0].label == 'box_pos'
    bag = tmp_path / 'bag'
    with BagWriter(bag, list(sim.legs), sensors=layout) as writer:
        writer.write_states(states)
    recorded = bag_topics(bag)
    for topic, msgtype in expected.items():
        assert recorded[topic].msgtype == msgtype and recorded[topic].count == len(states)
    last = [m for _, _, m in read_messages(bag, ['/rft/sensors/imu_gyro'])][-1]
    assert last.angular_velocity.z == gyro.angular_velocity.z


def test_the_bag_packs_imu_and_contacts_as_rosbags_serialises_them():
    """The bag's fast path (cdr.StateEncoder) writes the IMU and contacts byte for byte as
    rosbags serialises the messages `messages` builds (noise on: covariances not zero)."""
    from types import SimpleNamespace
    from rft_sim_ros.ros.bag import _CycleRecords
    from rft_sim_ros.ros.cdr import StateEncoder
    from rft_sim_ros.stamps import seconds_to_ns, split_ns
    sim = Simulation(load_scene('quadruped', overrides={
        'params.gait': 'none', 'sensors.imu': True, 'sensors.contacts': True,
        'sensors.imu_topic': '/base/imu', 'sensors.imu_noise.accel_std': 0.02}))
    state = publish_cycles(sim, 0.05)[-1]
    encoder = StateEncoder(state, '/base/imu')
    expected = messages.state_messages(FACTORY, state, plates=False, imu_topic='/base/imu')
    assert encoder.topics == [topic for topic, _ in expected]
    assert encoder.topics[-2:] == ['/base/imu', topics.FOOT_CONTACTS]
    records = _CycleRecords(encoder, [SimpleNamespace(id=i) for i in range(len(expected))])
    time_ns = seconds_to_ns(state.time)
    packed = records.payloads(records.pack(time_ns, encoder.arguments(state,
                                                                       *split_ns(time_ns))))
    for (topic, message), data in zip(expected, packed):
        assert data == bytes(FACTORY.typestore.serialize_cdr(message, message.__msgtype__)), \
            topic
    assert encoder.fits(state) and not encoder.fits(publish_cycles(
        Simulation(load_scene('quadruped', overrides={'params.gait': 'none'})), 0.01)[-1])
