"""ros/jazzy_types.py: a bag's message types are rosbags' own Jazzy definitions, kept in the
user's cache, so that a later bag does not load rosbags' whole Jazzy store; a damaged cache
file is made again."""
import subprocess
import sys
from types import SimpleNamespace

import pytest
from rosbags.typesys import Stores, get_typestore

from rft_sim_ros.ros import jazzy_types, topics

#: Every type a bag may record (what the warmup caches).
RECORDED = topics.RECORDABLE_TYPES


def test_the_recordable_types_are_those_a_bag_with_everything_records():
    model_sensors = [(kind, kind, None) for kind in ('touch', 'gyro', 'jointpos')]
    layout = SimpleNamespace(imu_topic=topics.IMU, contact_legs=('a',),
                             model_sensors=model_sensors)
    recorded = topics.published_topics(['a', 'b'], plates=True, terrain=True, sensors=layout)
    assert set(recorded.values()) == RECORDED


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache folder, and `typestore_for` forgetting what this process made."""
    monkeypatch.setenv('XDG_CACHE_HOME', str(tmp_path))
    jazzy_types.typestore_for.cache_clear()
    yield jazzy_types.cache_file()
    jazzy_types.typestore_for.cache_clear()


def _same_as_rosbags(typestore):
    full = get_typestore(Stores.ROS2_JAZZY)
    for name in RECORDED:
        assert typestore.generate_msgdef(name) == full.generate_msgdef(name), name
    assert set(typestore.fielddefs) < set(full.fielddefs)
    for name, definition in typestore.fielddefs.items():
        assert definition == full.fielddefs[name], name


def test_the_types_are_rosbags_jazzy_definitions_first_from_its_store_then_from_the_cache(
        cache):
    assert not cache.exists()
    _same_as_rosbags(jazzy_types.typestore_for(RECORDED))
    assert cache.is_file()
    jazzy_types.typestore_for.cache_clear()
    _same_as_rosbags(jazzy_types.typestore_for(RECORDED))  # (read back from the file)
    assert len(jazzy_types.typestore_for(RECORDED).fielddefs) < 60  # (not the store's 162)


def test_a_bag_writer_in_a_later_process_does_not_load_rosbags_jazzy_store(tmp_path):
    """What a recorded run's start costs: its bag writer takes its types from the cache the
    first writer filled."""
    probe = ('import sys; from rft_sim_ros.ros.bag import BagWriter; '
             f'BagWriter({str(tmp_path / "bag")!r} + sys.argv[1], ["a", "b"]).close(); '
             "print('rosbags.typesys.stores.ros2_jazzy' in sys.modules)")
    env = {'XDG_CACHE_HOME': str(tmp_path / 'cache'), 'PATH': '/usr/bin:/bin'}
    loaded = [subprocess.run([sys.executable, '-c', probe, str(i)], capture_output=True,
                             text=True, check=True, timeout=60, env=env).stdout.strip()
              for i in range(2)]
    assert loaded == ['True', 'False']  # the first filled the cache


def test_a_type_the_cache_lacks_is_taken_from_the_store_and_added(cache):
    jazzy_types.typestore_for(frozenset({topics.CLOCK_TYPE}))
    jazzy_types.typestore_for.cache_clear()
    _same_as_rosbags(jazzy_types.typestore_for(RECORDED))  # more than the file held
    assert set(jazzy_types._read(cache)) >= RECORDED | {topics.CLOCK_TYPE}


@pytest.mark.parametrize('damaged', [
    '{"not": json', '[]', 'null', '{"x": [[], [["f", [2]]]]}',
    '{"std_msgs/msg/String": [[], [["data", [1, "string"]]]]}',
    '{"std_msgs/msg/String": [[], [["data", [7, ["string", 0]]]]]}'])
def test_a_damaged_cache_file_is_made_again(cache, damaged):
    cache.parent.mkdir(parents=True)
    cache.write_text(damaged)
    _same_as_rosbags(jazzy_types.typestore_for(RECORDED))
    assert set(jazzy_types._read(cache)) >= RECORDED  # (written again, whole)
    assert [path.name for path in cache.parent.iterdir()] == [cache.name]  # (no leftovers)
