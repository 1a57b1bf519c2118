"""rosbag2 (MCAP) recording of the published topics, read back with rosbags."""
import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader, StoragePlugin, WriterError

from rft_sim_ros.ros import messages, topics
from rft_sim_ros.ros.bag import (BagWriter, TopicInfo, _CycleRecords, _Rosbag2Writer, bag_topics,
                                 read_messages)
from rft_sim_ros.ros import cdr
from rft_sim_ros.ros.cdr import StateEncoder
from rft_sim_ros.ros.factory import RosbagsFactory
from rft_sim_ros.stamps import seconds_to_ns, split_ns
from ros_test_support import make_state, make_terrain_update, messages_equal

LEGS = ('L1', 'R1', 'L2')
DT = 0.0125           # s of sim time between recorded states (publish rate 80 Hz)
N_STATES = 40
DIAGNOSTICS_EVERY = 8


def states(n=N_STATES, start=3.0):
    return [make_state(time=start + i * DT, legs=LEGS, seed=i) for i in range(n)]


def stamp_ns(time_msg):
    return time_msg.sec * 1_000_000_000 + time_msg.nanosec


def message_stamp_ns(topic, msg):
    if topic == topics.CLOCK:
        return stamp_ns(msg.clock)
    if topic == topics.TF:
        assert len({stamp_ns(t.header.stamp) for t in msg.transforms}) == 1
        return stamp_ns(msg.transforms[0].header.stamp)
    if topic == topics.PLATES:
        return stamp_ns(msg.markers[0].header.stamp)
    return stamp_ns(msg.header.stamp)


@pytest.fixture(scope='module')
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp('bags') / 'run'
    run = messages.RunStatus(scene='hexapod', real_time_factor=11.0)
    recorded_states = states()
    with BagWriter(path, LEGS, plates=True) as writer:
        for i, state in enumerate(recorded_states):
            writer.write_state(state)
            if i % DIAGNOSTICS_EVERY == 0:
                writer.write_diagnostics(state, run)
    return path, recorded_states


def test_bag_lists_the_published_topics_types_and_counts(recorded):
    path, recorded_states = recorded
    n_diag = len(range(0, N_STATES, DIAGNOSTICS_EVERY))
    expected = {topic: TopicInfo(msgtype, n_diag if topic == topics.DIAGNOSTICS else N_STATES)
                for topic, msgtype in topics.published_topics(LEGS, plates=True).items()}
    assert bag_topics(path) == expected


def test_bag_is_mcap_rosbag2_version_9(recorded):
    path, _ = recorded
    info = yaml.safe_load((path / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['version'] == 9
    assert info['storage_identifier'] == 'mcap'
    assert all(f.endswith('.mcap') for f in info['relative_file_paths'])
    assert info['message_count'] == sum(t.count for t in bag_topics(path).values())


def test_timestamps_are_sim_time_and_increase(recorded):
    path, recorded_states = recorded
    expected_ns = [seconds_to_ns(s.time) for s in recorded_states]
    by_topic = {}
    for topic, time_ns, msg in read_messages(path):
        assert message_stamp_ns(topic, msg) == time_ns
        by_topic.setdefault(topic, []).append(time_ns)
    for topic, times in by_topic.items():
        assert all(b > a for a, b in zip(times, times[1:])), topic
    assert by_topic[topics.JOINT_STATES] == expected_ns
    assert by_topic[topics.DIAGNOSTICS] == expected_ns[::DIAGNOSTICS_EVERY]


def test_clock_equals_sim_time(recorded):
    path, recorded_states = recorded
    clocks = [(time_ns, msg) for _, time_ns, msg in read_messages(path, [topics.CLOCK])]
    assert len(clocks) == N_STATES
    for state, (time_ns, msg) in zip(recorded_states, clocks):
        assert time_ns == stamp_ns(msg.clock) == seconds_to_ns(state.time)
        assert msg.clock.sec + msg.clock.nanosec * 1e-9 == pytest.approx(state.time, abs=1e-9)


def test_bag_holds_exactly_the_messages_the_node_publishes(recorded):
    path, recorded_states = recorded
    factory = RosbagsFactory()
    expected = [pair for state in recorded_states
                for pair in messages.state_messages(factory, state, plates=True)]
    read = [(topic, msg) for topic, _, msg in read_messages(path)
            if topic != topics.DIAGNOSTICS]
    assert sorted(t for t, _ in read) == sorted(t for t, _ in expected)
    for topic in {t for t, _ in expected}:
        mine = [m for t, m in expected if t == topic]
        theirs = [m for t, m in read if t == topic]
        assert all(messages_equal(a, b) for a, b in zip(mine, theirs)), topic


def test_read_messages_filters_topics(recorded):
    path, _ = recorded
    wrench = topics.leg_wrench_topic('R1')
    assert {t for t, _, _ in read_messages(path, [wrench, topics.ODOM])} == {wrench,
                                                                             topics.ODOM}
    assert list(read_messages(path, ['/not/recorded'])) == []


def test_plates_are_only_recorded_when_asked(tmp_path):
    with BagWriter(tmp_path / 'bag', ['L1'], plates=False) as writer:
        for state in states(3):
            writer.write_state(dataclasses.replace(state, legs=state.legs[:1]))
    recorded_topics = bag_topics(tmp_path / 'bag')
    assert topics.PLATES not in recorded_topics
    assert recorded_topics[topics.CLOCK].count == 3
    assert recorded_topics[topics.DIAGNOSTICS].count == 0


def test_writer_refuses_foreign_topics_and_types(tmp_path):
    factory = RosbagsFactory()
    state = make_state(legs=('L1',))
    with BagWriter(tmp_path / 'bag', ['L1']) as writer:
        with pytest.raises(KeyError, match='/chatter'):
            writer.write('/chatter', messages.clock_message(factory, state), 0)
        with pytest.raises(TypeError, match='Odometry'):
            writer.write(topics.ODOM, messages.clock_message(factory, state), 0)
    assert all(info.count == 0 for info in bag_topics(tmp_path / 'bag').values())


def test_terrain_publications_are_recorded_as_a_cloud_and_one_marker_array(tmp_path):
    """Each terrain publication: its cloud where it has one, and one MarkerArray of all its
    markers (a whole re-send, DELETEALL included, in one message), read back by rosbags;
    a bare Marker is refused on /rft/terrain/marker."""
    updates = [make_terrain_update(clear=True, time=0.0),          # the first: whole
               make_terrain_update(clear=False, time=0.5),         # changes
               make_terrain_update(clear=True, time=0.6, cloud=False)]  # a marker re-send
    with BagWriter(tmp_path / 'bag', [], terrain=True) as writer:
        for update in updates:
            writer.write_terrain(update)
        marker = messages.terrain_markers(writer.factory, updates[0])[0]
        with pytest.raises(TypeError, match='MarkerArray'):
            writer.write(topics.TERRAIN_MARKER, marker, 0)
    recorded_topics = bag_topics(tmp_path / 'bag')
    assert recorded_topics[topics.TERRAIN] == TopicInfo(topics.POINT_CLOUD_TYPE, 2)
    assert recorded_topics[topics.TERRAIN_MARKER] == TopicInfo(topics.MARKER_ARRAY_TYPE, 3)
    arrays = list(read_messages(tmp_path / 'bag', [topics.TERRAIN_MARKER]))
    assert [time_ns for _, time_ns, _ in arrays] == [0, 500_000_000, 600_000_000]
    factory = RosbagsFactory()
    for update, (_, _, array) in zip(updates, arrays):
        expected = messages.terrain_markers(factory, update)
        assert len(array.markers) == len(expected) == 2 + update.clear
        assert all(messages_equal(a, b) for a, b in zip(array.markers, expected))


def test_writer_refuses_an_existing_folder(tmp_path):
    (tmp_path / 'bag').mkdir()
    with pytest.raises(WriterError, match='exists'):
        BagWriter(tmp_path / 'bag', ['L1'])
    assert not list((tmp_path / 'bag').iterdir())


def test_leg_wrench_read_back_gives_vertical_force(recorded):
    path, recorded_states = recorded
    forces = [msg.wrench.force.z
              for _, _, msg in read_messages(path, [topics.leg_wrench_topic('L2')])]
    np.testing.assert_array_equal(forces, [s.legs[2].force[2] for s in recorded_states])


@pytest.mark.parametrize('legs, time, joints', [
    (LEGS, 3.0125, True), ((), 0.0, True), (('a', 'front_left_long_name', 'xy'), 12345.6789, True),
    (('plate',), 0.01, False)])
def test_packed_state_topics_are_the_bytes_rosbags_serialises(legs, time, joints):
    """joints False: a scene without joints (plate_drop), whose empty float64[] take no
    alignment padding (CDR aligns an element, not an empty sequence)."""
    state = make_state(time=time, legs=legs, seed=3)
    if not joints:
        state = dataclasses.replace(state, joint_names=(), joint_positions=np.zeros(0),
                                    joint_velocities=np.zeros(0), joint_efforts=np.zeros(0))
    encoder = StateEncoder(state)
    factory = RosbagsFactory()
    expected = [(topic, message) for topic, message
                in messages.state_messages(factory, state, plates=False)]
    assert encoder.topics == [topic for topic, _ in expected]
    # as the bag holds them: the cycle's records packed in one call, each message's bytes
    records = _CycleRecords(encoder, [SimpleNamespace(id=i) for i in range(len(expected))])
    time_ns = seconds_to_ns(time)
    packed = records.payloads(records.pack(time_ns, encoder.arguments(state,
                                                                       *split_ns(time_ns))))
    for (topic, message), data in zip(expected, packed):
        assert data == bytes(factory.typestore.serialize_cdr(message, message.__msgtype__)), \
            topic


def test_batched_cycles_write_the_file_rosbags_writes_message_by_message(tmp_path):
    """Enough cycles to close MCAP chunks (1 MiB) on the way: same bytes, same metadata."""
    recorded_states = states(n=900)
    batched, plain = tmp_path / 'batched' / 'run', tmp_path / 'plain' / 'run'  # same names
    with BagWriter(batched, LEGS) as writer:  # in batches of 37 cycles, and one by one
        for start in range(0, 600, 37):
            writer.write_states(recorded_states[start:min(start + 37, 600)])
        for state in recorded_states[600:]:
            writer.write_state(state)
    reference = _Rosbag2Writer(plain, version=9,
                               storage_plugin=StoragePlugin.MCAP)
    reference.open()
    factory = RosbagsFactory()
    connections = {topic: reference.add_connection(topic, msgtype, typestore=factory.typestore)
                   for topic, msgtype in topics.published_topics(LEGS, plates=False).items()}
    for state in recorded_states:
        for topic, message in messages.state_messages(factory, state, plates=False):
            reference.write(connections[topic], seconds_to_ns(state.time),
                            factory.typestore.serialize_cdr(message, message.__msgtype__))
    reference.close()
    assert (batched / 'run.mcap').read_bytes() == (plain / 'run.mcap').read_bytes()
    assert (batched / 'metadata.yaml').read_text() == (plain / 'metadata.yaml').read_text()
    assert bag_topics(batched)[topics.CLOCK].count == 900


def test_bag_metadata_keeps_each_value_on_its_line_as_rosbag2_writes_it(recorded):
    # ruamel.yaml's C emitter (a dependency: 4x faster than its Python one, which folds the
    # long type description hashes onto a second line)
    path, _ = recorded
    lines = (path / 'metadata.yaml').read_text().splitlines()
    hashes = [line for line in lines if 'type_description_hash:' in line]
    assert hashes and all(line.split(': ')[1].startswith('RIHS01_') for line in hashes)


def test_bag_metadata_names_the_jazzy_distribution(recorded):
    path, _ = recorded
    info = yaml.safe_load((path / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['ros_distro'] == 'jazzy'
    with Reader(path) as reader:   # the copy inside the MCAP file, which ros2 bag reads
        assert reader.ros_distro == 'jazzy'
    mcap = next(path.glob('*.mcap')).read_bytes()
    assert b'ros_distro: jazzy' in mcap and b'ros_distro: rosbags' not in mcap


@pytest.mark.parametrize('status', [
    messages.RunStatus(scene='hexapod', real_time_factor=11.25),
    messages.RunStatus(scene='a', real_time_factor=float('nan'), stable=False,
                       problem='at t = 1.0000 s: runaway speed 2e+03',
                       commands_rejected={'not_finite': 2, 'unknown_joint': 13}, paused=True),
    messages.RunStatus(scene='', real_time_factor=0.0, paused=True)])
def test_packed_diagnostics_are_the_bytes_rosbags_serialises(status):
    state = make_state(time=7.25, legs=LEGS)
    factory = RosbagsFactory()
    message = messages.diagnostics_message(factory, state, status)
    packed = cdr.diagnostics(messages.diagnostic_fields(state, status),
                             *split_ns(seconds_to_ns(state.time)))
    assert packed == bytes(factory.typestore.serialize_cdr(message, message.__msgtype__))
