"""Headless runs recorded into a rosbag2 (MCAP) with the node's topics (`rft-sim run`), and
run_scene's schedule of mid-run changes."""
import json

import numpy as np
import pytest

from rft_sim_ros.cli import main
from rft_sim_ros.ros import topics
from rosbags.rosbag2 import Reader

from rft_sim_ros.ros.bag import BagWriter, bag_topics, read_messages
from rft_sim_ros.ros.recording import BagRecorder
from rft_sim_ros.ros.runtime import SimRuntime
from rft_sim_ros.ros.terrain import TerrainFeed
from rft_sim_ros.stamps import seconds_to_ns
from rft_sim_ros.sim.runner import run_scene
from rft_sim_ros.scenes.config import load_scene
from rft_sim_ros.sim.simulation import Simulation
from ros_test_support import SERVO_RIG

DURATION = 0.3        # s
CHANGE_AT = 0.2       # s: zeta 3.75 -> 1.0
RATE = 100            # Hz: the scene's publish rate


def stamp_ns(time_msg):
    return time_msg.sec * 1_000_000_000 + time_msg.nanosec


def diagnostic_values(msg):
    status = msg.status[0]
    return status, {kv.key: kv.value for kv in status.values}


@pytest.fixture(scope='module')
def press_run(tmp_path_factory):
    """plate_press from the surface down, zeta lowered mid-run, recorded by `rft-sim run`."""
    out = tmp_path_factory.mktemp('press') / 'run'
    code = main(['run', 'plate_press', '--duration', str(DURATION), '--set', 'start_height=0',
                 '--set-at', f'{CHANGE_AT}:zeta=1.0', '--out', str(out), '--quiet'])
    assert code == 0
    return out


def test_bag_holds_the_node_topics_with_one_message_per_publish_period(press_run):
    expected_count = round(RATE * DURATION) + 1  # and the initial state, as the node
    recorded = bag_topics(press_run / 'bag')
    assert {t: i.msgtype for t, i in recorded.items()} == topics.published_topics(
        ['plate'], plates=False)
    for topic, info in recorded.items():
        if topic != topics.DIAGNOSTICS:
            assert info.count == expected_count, topic
    assert recorded[topics.DIAGNOSTICS].count == 2   # the first state, then the zeta change
    summary = json.loads((press_run / 'summary.json').read_text())
    assert 0 < summary['recording_time_s'] < summary['wall_time_s']


def test_stamps_increase_and_clock_is_sim_time(press_run):
    expected = [seconds_to_ns(k / RATE) for k in range(round(RATE * DURATION) + 1)]
    by_topic = {}
    for topic, time_ns, msg in read_messages(press_run / 'bag'):
        by_topic.setdefault(topic, []).append(time_ns)
        if topic == topics.CLOCK:
            assert stamp_ns(msg.clock) == time_ns
        elif topic == topics.TF:
            assert all(stamp_ns(t.header.stamp) == time_ns for t in msg.transforms)
        else:
            assert stamp_ns(msg.header.stamp) == time_ns
    for topic, times in by_topic.items():
        assert all(b > a for a, b in zip(times, times[1:])), topic
    assert by_topic[topics.CLOCK] == pytest.approx(expected, abs=1)
    summary = json.loads((press_run / 'summary.json').read_text())
    assert by_topic[topics.CLOCK][-1] == seconds_to_ns(summary['sim_time_s'])


def test_zeta_change_shows_on_diagnostics_and_in_the_wrench_from_the_next_step(press_run):
    diagnostics = [(t, *diagnostic_values(m))
                   for _, t, m in read_messages(press_run / 'bag', [topics.DIAGNOSTICS])]
    (t0, s0, v0), (t1, s1, v1) = diagnostics
    assert float(v0['zeta_n_per_cm3']) == 3.75 and float(v1['zeta_n_per_cm3']) == 1.0
    assert t1 == seconds_to_ns(CHANGE_AT + 1 / RATE)
    assert s0.message == s1.message == 'running'
    depth = {t: -m.pose.pose.position.z + 0.001   # plate bottom below the surface, m
             for _, t, m in read_messages(press_run / 'bag', [topics.ODOM])}
    force = {t: m.wrench.force.z
             for _, t, m in read_messages(press_run / 'bag', ['/rft/plate/wrench'])}
    before, at, after = (seconds_to_ns(CHANGE_AT + k / RATE) for k in (-1, 0, 1))
    stiffness = {t: force[t] / depth[t] for t in (before, at, after)}  # N/m = zeta A
    assert stiffness[at] == pytest.approx(3.75e6 * 0.01, rel=0.05)
    assert stiffness[before] == pytest.approx(stiffness[at], rel=0.01)
    assert stiffness[after] / stiffness[at] == pytest.approx(1.0 / 3.75, rel=0.05)


def test_no_bag_writes_none(tmp_path):
    out = tmp_path / 'run'
    assert main(['run', 'plate_press', '--duration', '0.02', '--out', str(out), '--quiet',
                 '--no-bag']) == 0
    assert (out / 'summary.json').is_file() and not (out / 'bag').exists()
    assert json.loads((out / 'summary.json').read_text())['recording_time_s'] < 1e-3


def test_an_existing_bag_is_not_overwritten(tmp_path, capsys):
    out = tmp_path / 'run'
    (out / 'bag').mkdir(parents=True)
    assert main(['run', 'plate_press', '--duration', '0.02', '--out', str(out), '--quiet']) == 2
    assert "holds an earlier run's outputs (bag)" in capsys.readouterr().err
    assert not list((out / 'bag').iterdir()) and not (out / 'summary.json').exists()


def test_plates_flag_records_the_plate_markers(tmp_path):
    out = tmp_path / 'run'
    assert main(['run', 'plate_press', '--duration', '0.05', '--set', 'start_height=0',
                 '--out', str(out), '--quiet', '--plates', '--set-at', '0:zeta=2']) == 0
    recorded = bag_topics(out / 'bag')
    assert recorded[topics.PLATES].count == 6  # (sim time 0 and five cycles)
    markers = [m.markers[0] for _, _, m in read_messages(out / 'bag', [topics.PLATES])]
    assert len(markers[-1].points) > 0


@pytest.mark.parametrize('bad, words', [
    ('0.1:zeta=-1', 'zeta must be > 0'), ('0.1:zeta=.nan', 'finite'),
    ('0.1:zeta=soft', "zeta must be a number in N/cm^3, got 'soft'"),
    ('0.1:timestep=0.002', 'can change zeta'), ('soon:zeta=1', 'T:key=value'),
    ('-1:zeta=1', 'T >= 0'), ('0.1', 'T:key=value'), ('0.1:zeta', 'key=value')])
def test_bad_set_at_is_one_error_line(tmp_path, capsys, bad, words):
    out = tmp_path / 'run'
    assert main(['run', 'plate_press', '--duration', '0.02', '--out', str(out), '--quiet',
                 f'--set-at={bad}']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('rft-sim: error:') and words in err[0]
    assert not out.exists()


def test_two_changes_of_a_setting_at_one_time_are_refused(tmp_path, capsys):
    assert main(['run', 'plate_press', '--duration', '0.02', '--out', str(tmp_path / 'run'),
                 '--quiet', '--set-at', '0.01:zeta=1.0', '--set-at', '0.01:zeta=2.0']) == 2
    assert capsys.readouterr().err.strip() == ('rft-sim: error: --set-at changes zeta twice at '
                                               '0.01 s: give one value')


# --- run_scene: schedule and recorder hooks -------------------------------------------------

def test_scheduled_actions_run_once_at_their_step_before_the_next_step():
    seen = []
    scene = load_scene(SERVO_RIG)
    summary = run_scene(scene, duration=0.05, progress=False, schedule=[
        (0.0235, lambda sim: seen.append(('b', sim.steps, sim.time))),
        (0.0, lambda sim: seen.append(('a', sim.steps, sim.time))),
        (0.0235, lambda sim: seen.append(('c', sim.steps, sim.time))),
        (1.0, lambda sim: seen.append(('never', sim.steps, sim.time)))])
    assert summary['steps'] == 50
    assert [(name, steps) for name, steps, _ in seen] == [('a', 0), ('b', 24), ('c', 24)]
    assert seen[1][2] == pytest.approx(0.024)


def test_schedule_times_are_checked():
    with pytest.raises(ValueError, match='scheduled time'):
        run_scene(load_scene(SERVO_RIG), duration=0.01, progress=False,
                  schedule=[(float('nan'), print)])


def test_recorder_reports_a_divergence_and_finishes_the_bag(tmp_path):
    scene = load_scene(SERVO_RIG)
    recorder = BagRecorder(tmp_path / 'bag', scene)
    summary = run_scene(scene, duration=0.2, progress=False, recorders=[recorder],
                        schedule=[(0.1, lambda sim: sim.data.qvel.__setitem__(
                            slice(None), 1e5))])
    reason = summary['reason']
    assert not summary['stable'] and ('runaway' in reason or 'unstable' in reason)
    # (its outcome is of the looks before, and says so: not a verdict on the blown-up state)
    assert summary['outcome']['words'].startswith('until the run stopped at t = 0.1')
    recorded = bag_topics(tmp_path / 'bag')
    assert recorded[topics.JOINT_STATES].count == 11  # (sim time 0 and ten cycles)
    last_time, last = list(read_messages(tmp_path / 'bag', [topics.DIAGNOSTICS]))[-1][1:]
    status, values = diagnostic_values(last)
    assert status.level == 2 and status.message == reason.removeprefix('diverged ')
    assert values['stable'] == 'false'
    assert last_time == seconds_to_ns(0.1)
    js = [m for _, _, m in read_messages(tmp_path / 'bag', [topics.JOINT_STATES])]
    assert all(np.all(np.isfinite(m.velocity)) for m in js)


def _recorded_at(path, time_ns):
    """[(topic, CDR bytes)] of the rosbag2 at `path` at `time_ns`, in the bag's order."""
    with Reader(path) as reader:
        return [(connection.topic, bytes(data))
                for connection, t, data in reader.messages() if t == time_ns]


def test_the_bag_starts_with_what_the_node_publishes_at_sim_time_0(tmp_path):
    """The node's first tick publishes the initial state at sim time 0 (/clock 0, the state
    topics, the plates, the whole sand surface and its markers, /diagnostics with no
    real-time factor measured yet): a headless run's bag holds the same messages, byte for
    byte, at 0."""
    deformable = {'sand.deformable.enabled': True, 'sand.deformable.size': [0.5, 0.5]}
    scene = load_scene('plate_drop', deformable)
    run_scene(scene, duration=0.05, progress=False,
              recorders=[BagRecorder(tmp_path / 'run', scene, plates=True)])
    sim = Simulation(load_scene('plate_drop', deformable))
    with BagWriter(tmp_path / 'node', list(sim.legs), plates=True, terrain=True) as sink:
        SimRuntime(sim, sink, publish_rate=100.0, plates=True,
                   terrain=TerrainFeed(sim.engine.surface), clock=lambda: 0.0).tick()
    node = _recorded_at(tmp_path / 'node', 0)
    assert {topic for topic, _ in node} == set(topics.published_topics(
        ['plate'], plates=True, terrain=True))
    assert sorted(_recorded_at(tmp_path / 'run', 0)) == sorted(node)


def test_recorders_are_closed_when_the_scene_cannot_be_built(tmp_path):
    scene = load_scene(SERVO_RIG, {'rft.sand_bodies': ['foot', 'no_such_body'],
                                   'legs': {'leg': ['foot']}})
    recorder = BagRecorder(tmp_path / 'bag', scene)
    with pytest.raises(ValueError, match='no_such_body'):
        run_scene(scene, duration=0.01, progress=False, recorders=[recorder])
    assert all(info.count == 0 for info in bag_topics(tmp_path / 'bag').values())
