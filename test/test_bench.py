"""The benchmark's own logic (the measurements themselves run in `rft-sim bench`)."""
import math
from pathlib import Path

import pytest

from rft_sim_ros.bench import pareto
from rft_sim_ros.bench.report import markdown


def test_pareto_front_keeps_only_undominated_points():
    points = [(1.0, 0.10), (2.0, 0.05), (3.0, 0.05), (0.5, 0.50), (2.5, 0.01), (4.0, 0.2)]
    assert pareto.pareto_front(points) == [0, 1, 3, 4]


def test_equal_errors_within_rounding_favour_the_faster_run():
    points = [(0.049, 0.0030000000001), (0.064, 0.0029999999999)]
    assert pareto.pareto_front(points) == [0]


def test_every_sweep_includes_its_reference_finer_than_its_grid():
    for name, sweep in {**pareto.SWEEPS, **pareto.QUICK_SWEEPS}.items():
        plates, timestep = sweep.reference
        assert plates >= max(sweep.plates) and timestep <= min(sweep.timesteps), name


def test_report_marks_front_default_and_unstable_runs():
    results = {'machine': {'cpu': 'x', 'cores': 2, 'python': '3', 'mujoco': '4', 'numpy': '2'},
               'speed_against_error': [{
                   'scene': 's', 'metric': 'm',
                   'reference': {'plates_per_body': 10, 'timestep_s': 1e-4, 'metric': 1.0},
                   'rows': [{'plates_per_body': 5, 'timestep_s': 1e-3, 'wall_s_per_sim_s': 0.1,
                             'metric': 1.01, 'relative_error': 0.01, 'default': True,
                             'on_front': True},
                            {'plates_per_body': 5, 'timestep_s': 2e-3, 'wall_s_per_sim_s': 0.05,
                             'metric': None, 'relative_error': math.inf, 'default': False,
                             'on_front': False}]}]}
    text = markdown(results)
    assert '| **5 (default)** | **1** |' in text
    assert '| 5 | 2 | 0.050 | unstable | inf |' in text
    assert 'at the start: unknown; at the end: unknown' in text


def test_report_names_the_machine_and_its_load():
    from rft_sim_ros.sim.runner import machine_info
    machine = machine_info()
    assert machine['cpu'] and machine['cores'] >= 1
    assert len(machine['load_average']) == 3 and min(machine['load_average']) >= 0.0
    text = markdown({'machine': machine, 'load_average_at_end': [1.5, 0.25, 3.0]})
    assert f'Machine: {machine["cpu"]}, {machine["cores"]} cores' in text
    assert 'at the end: 1.50, 0.25, 3.00' in text


def test_hexapod_trial_times_the_walk_apart_from_the_drop():
    from rft_sim_ros.bench.step_cost import hexapod_trial
    summary, walk = hexapod_trial({'cycles': 1, 'settle_time': 0.4, 'rft.plates_per_body': 100})
    assert summary['sim_time_s'] == pytest.approx(1.4, abs=1e-3)
    assert walk['sim_time_s'] == pytest.approx(1.0, abs=1e-3)   # one cycle at 1 Hz
    assert 0.0 < walk['wall_time_s'] < summary['wall_time_s']
    assert walk['real_time_factor'] == pytest.approx(walk['sim_time_s'] / walk['wall_time_s'])


def test_hexapod_trial_with_its_bag_records_the_run(tmp_path):
    from rft_sim_ros.bench.step_cost import hexapod_trial
    from rft_sim_ros.ros.bag import bag_topics
    summary, _ = hexapod_trial({'cycles': 1, 'settle_time': 0.4, 'rft.plates_per_body': 100},
                               bag=tmp_path / 'bag')
    assert bag_topics(tmp_path / 'bag')['/clock'].count == 141   # 0 and 1.4 s at 100 Hz
    assert 0.0 < summary['recording_time_s'] < summary['wall_time_s']


def test_hexapod_step_cost_runs_both_loops():
    from rft_sim_ros.bench.step_cost import hexapod_step_cost
    result = hexapod_step_cost(chunks=1, chunk_steps=20, settle_steps=20,
                               overrides={'rft.plates_per_body': 50})
    assert result['sand_engine_step_s'] > 0 and result['rigid_step_s'] > 0
    assert result['ratio_engine_to_rigid'] == pytest.approx(
        result['sand_engine_step_s'] / result['rigid_step_s'])


@pytest.mark.slow  # (compiles the deformable kernels in a worker process: a benchmark's cost)
def test_engine_step_worker_times_one_gait_cycle_of_the_walk(tmp_path):
    """The terrain-cost worker: the code it imported, the cycle's steps, a CPU time per step,
    and where the sand bodies went on both axes: the crab hexapod, x -0.35 .. 0.35 m across
    its walk, walked along +y, staying on the bed laid along that walk."""
    from rft_sim_ros.bench.terrain_cost import (CODE, START_EXTENT, WALK_SPEED_BOUND, Worker,
                                                cases, check_on_surface, laid_along_walk)
    bed = dict((label, overrides) for label, overrides, _ in cases(tmp_path, rounds=1))[
        'deformable 2 m x 2 m, 1 cm']
    worker = Worker(CODE, {'rft.plates_per_body': 50, **bed}, tmp_path)
    try:
        assert Path(worker.info['package']).resolve() == CODE / 'rft_sim_ros' / '__init__.py'
        assert worker.info['cycle_steps'] == 1250  # 1 Hz gait at 0.8 ms
        assert 0.0 < worker.chunk() < 0.01
        (x_low, x_high), (y_low, y_high) = worker.extent
        assert -0.4 < x_low < -0.3 and 0.3 < x_high < 0.4
        assert START_EXTENT[0] <= y_low and START_EXTENT[1] < y_high
        assert y_high < START_EXTENT[1] + 2.0 * WALK_SPEED_BOUND  # two 1 s cycles walked
        check_on_surface('bed', worker.extent, *laid_along_walk(1))
    finally:
        worker.close()
    assert worker.process.returncode == 0


def test_terrain_cost_names_the_code_by_its_commit(tmp_path):
    """A report names the code it measured by its git commit, not by a path of the machine."""
    from rft_sim_ros.bench.terrain_cost import CODE, commit
    if not (CODE / '.git').exists():
        pytest.skip('the package is not in a git checkout here')
    head = commit(CODE)
    assert head and '/' not in head and len(head.split('+')[0]) >= 7
    assert commit(tmp_path) is None


def test_terrain_cost_lays_its_surfaces_along_the_whole_walk():
    """Grids and beds cover the stretch walked along +y in the rounds at the speed bound, 2 m
    long or longer, and are 2 m wide across it (x), centred on the robot; a case whose
    bodies leave them on either axis stops the benchmark."""
    from rft_sim_ros.bench.terrain_cost import (START_EXTENT, WALK_AXIS, WALK_SPEED_BOUND,
                                                check_on_surface, laid_along_walk)
    assert WALK_AXIS == 1  # the crab hexapod walks sideways, along world +y
    for rounds, side in ((1, 2.0), (3, 2.0), (20, None)):
        centre, size = laid_along_walk(rounds)
        assert centre[0] == 0.0 and size[0] == 2.0
        low, high = centre[1] - 0.5 * size[1], centre[1] + 0.5 * size[1]
        assert low < START_EXTENT[0] and high > START_EXTENT[1] + 2.0 * rounds * WALK_SPEED_BOUND
        assert size[1] == (side or pytest.approx(high - low)) and size[1] >= 2.0
        inside = [[-0.999, 0.999], [low + 0.001, high - 0.001]]
        check_on_surface('case', inside, centre, size)
        with pytest.raises(RuntimeError, match='case: the hexapod walked beyond .* at y'):
            check_on_surface('case', [inside[0], [low + 0.001, high + 0.001]], centre, size)
        with pytest.raises(RuntimeError, match='case: the hexapod walked beyond .* at x'):
            check_on_surface('case', [[-1.001, 0.999], inside[1]], centre, size)


@pytest.mark.slow
def test_terrain_cost_writes_every_surface_against_the_plane(tmp_path):
    import json
    from rft_sim_ros.bench.terrain_cost import main
    main(['--out', str(tmp_path), '--rounds', '1', '--processes', '2'])
    results = json.loads((tmp_path / 'terrain_cost.json').read_text())
    assert results['cases']['plane']['ratio_to_plane'] == 1.0 and results['processes'] == 2
    assert len(results['cases']) == 9 and results['machine']['cores'] >= 1
    assert '| deformable 8 m x 8 m, 1 cm |' in (tmp_path / 'terrain_cost.md').read_text()


def test_other_bodies_cost_compares_the_same_robot_with_and_without_their_plates():
    from rft_sim_ros.bench.other_bodies import step_cost_ratio
    cost = step_cost_ratio('quadruped', {'gait': 'none'}, warm_s=0.05, chunks=2, chunk_steps=20)
    assert cost['other_plates'] > 0 and cost['others_in_sand'] == 0  # trunk, calves: above
    assert cost['with_us'] > 0 and cost['without_us'] > 0 and cost['ratio'] > 0


def test_dof_scaling_adds_degrees_of_freedom_only():
    """The chain adds hinges in the air: nv grows by one a link, the plates in the sand do
    not change, and the body still stands."""
    from rft_sim_ros.bench.dof_scaling import body_with_chain, dof_scaling
    assert body_with_chain(0)[0].nv == 14 and body_with_chain(5)[0].nv == 19
    rows = dof_scaling((0, 6), chunks=1, chunk_steps=20, settle_steps=300)
    assert [row['nv'] for row in rows] == [14, 20]
    assert rows[0]['plates_in_sand'] == rows[1]['plates_in_sand'] > 0
    assert all(row['standing'] and row['sand_step_s'] > 0 and row['rigid_step_s'] > 0
               for row in rows)


def test_loop_parts_add_up_to_the_loop_and_leave_nothing_wrapped():
    """A short hexapod run split into its parts: each part took time, the parts of the loop
    (with its rest) add up to it and stay within it, and every function timed is itself
    again afterwards."""
    from rft_sim_ros.bench import loop_parts as bench
    from rft_sim_ros.sand.engine import SandEngine
    from rft_sim_ros.sim import runner
    from rft_sim_ros.sim.simulation import Simulation
    timed = (SandEngine.step, Simulation.__init__, Simulation.step, Simulation._control_tick,
             runner._record)
    parts = bench.loop_parts('hexapod', runs=1, duration=0.2,
                             overrides={'rft.plates_per_body': 40})
    assert (SandEngine.step, Simulation.__init__, Simulation.step, Simulation._control_tick,
            runner._record) == timed
    top = [parts[part] for part in bench._TOP]
    assert all(value > 0 for value in top)
    assert sum(top) + parts['rest'] == pytest.approx(parts['loop'])
    assert sum(top) < parts['loop']
    tick = ('  scenario control', '  servo targets', '  outcome watch', '  divergence check')
    assert all(0 < parts[part] < parts['loop'] for part in tick)
