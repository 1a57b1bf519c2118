"""A run's outputs are never lost or ambiguous: no run writes over an earlier one unless told
(--overwrite), an exception in a scenario ends the run with its summary, time series and bag
kept, a scenario that cannot be imported is one error before anything is written, and the
CLI prints a short summary (the JSON only with --json; --quiet: errors only)."""
import json
import re

from rosbags.highlevel import AnyReader

from rft_sim_ros.cli import main

#: A short, cheap run (the bundled plate drop).
SHORT = ['run', 'plate_drop', '--duration', '0.05', '--set', 'drop_height=0.01',
         '--plates-per-body', '50']


def error_lines(capsys):
    """The `rft-sim: error:` lines of the captured stderr, and the captured stdout."""
    captured = capsys.readouterr()
    return [line for line in captured.err.splitlines() if 'error:' in line], captured.out


def test_a_run_never_writes_over_an_earlier_one_unless_told(tmp_path, capsys):
    out = tmp_path / 'run'
    assert main([*SHORT, '--out', str(out), '--no-bag', '--quiet']) == 0
    first = (out / 'summary.json').read_text()
    for bag in ([], ['--no-bag']):  # with or without a bag, the earlier run is kept
        assert main([*SHORT, '--zeta', '1', '--out', str(out), '--quiet', *bag]) == 2
        errors, _ = error_lines(capsys)
        assert len(errors) == 1 and "holds an earlier run's outputs" in errors[0]
        assert '--overwrite' in errors[0] and (out / 'summary.json').read_text() == first
    # refused in its set-up, a replacing run puts the earlier run back
    assert main([*SHORT, '--out', str(out), '--overwrite', '--sand-bodies', 'hoof']) == 2
    assert (out / 'summary.json').read_text() == first and not (out / 'bag').exists()
    assert main([*SHORT, '--zeta', '1', '--out', str(out), '--overwrite', '--quiet']) == 0
    assert json.loads((out / 'summary.json').read_text())['zeta'] == 1.0
    assert (out / 'bag').is_dir()
    assert [p.name for p in tmp_path.iterdir()] == ['run']  # nothing set aside is left


def test_a_folder_of_other_files_is_refused_even_with_overwrite(tmp_path, capsys):
    (tmp_path / 'notes.txt').write_text('mine')
    assert main([*SHORT, '--out', str(tmp_path), '--overwrite', '--quiet']) == 2
    errors, _ = error_lines(capsys)
    assert len(errors) == 1 and 'holds other files (notes.txt)' in errors[0]
    assert [p.name for p in tmp_path.iterdir()] == ['notes.txt']


FAILING = """from rft_sim_ros.scenes.scenarios import BaseScenario


class Scenario(BaseScenario):
    def control(self, sim):
        if sim.time > 0.02:
            self.ratio = 1.0 / 0.0
"""
SCENE = """scenario: {file}
model: plate.xml
duration: 0.1
rft: {{sand_bodies: [plate], plates_per_body: 50}}
"""


def _scene(tmp_path, source):
    (tmp_path / 'mine.py').write_text(source)
    (tmp_path / 'scene.yaml').write_text(SCENE.format(file='mine.py'))
    return tmp_path / 'scene.yaml'


def test_an_exception_in_a_scenario_ends_the_run_with_its_outputs_kept(tmp_path, capsys):
    out = tmp_path / 'run'
    assert main(['run', str(_scene(tmp_path, FAILING)), '--out', str(out), '--quiet']) == 1
    errors, stdout = error_lines(capsys)
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['stable'] is False and summary['generic_metrics']['stable'] is False
    line = f'{tmp_path / "mine.py"}:7: ZeroDivisionError: float division by zero'
    assert summary['reason'].startswith('scenario failed at t = 0.02')
    assert summary['reason'].endswith(f'the scenario raised at {line}')
    assert 0.02 <= summary['sim_time_s'] < 0.03
    assert len(errors) == 1 and line in errors[0] and 'scenario_traceback.log' in errors[0]
    assert stdout == ''  # --quiet: errors only
    assert 'Traceback' in (out / summary['scenario_traceback']).read_text()
    assert len((out / 'timeseries.csv').read_text().splitlines()) == 1 + 2  # 0.01, 0.02 s
    with AnyReader([out / 'bag']) as bag:  # closed, readable, up to the failure
        assert max(time_ns for _, time_ns, _ in bag.messages()) >= 20_000_000


def test_a_scenario_that_cannot_be_imported_is_one_error_before_anything_is_written(
        tmp_path, capsys):
    out = tmp_path / 'run'
    scene = _scene(tmp_path, FAILING.replace('def control(self, sim):', 'def control(self sim):'))
    assert main(['run', str(scene), '--out', str(out)]) == 2
    errors, _ = error_lines(capsys)
    assert len(errors) == 1 and f'{tmp_path / "mine.py"}:5: SyntaxError' in errors[0]
    assert not out.exists()


def test_the_cli_prints_a_short_summary_or_the_json_asked_for(tmp_path, capsys):
    assert main([*SHORT, '--out', str(tmp_path / 'a'), '--no-bag']) == 0
    lines = capsys.readouterr().out.splitlines()
    assert 2 <= len(lines) <= 6
    assert lines[0].startswith('plate_drop: stable, 0.05 s of sim time')
    # the loop's real-time factor, and the whole run's wall time, which holds the loop's
    loop, first, whole = re.fullmatch(
        r'.* in (\S+) s \(real-time factor \S+; first step at (\S+) s, (\S+) s in all, '
        r'set-up and files included\)', lines[0]).groups()
    assert 0 < float(loop) < float(whole) and 0 < float(first) < float(whole)
    assert lines[1].startswith('  outcome: upright')  # the summary's outcome words
    assert 'max_sinkage_m' in lines[2] and lines[-1].startswith(f'  wrote {tmp_path / "a"}/')
    assert main([*SHORT, '--out', str(tmp_path / 'b'), '--no-bag', '--json', '--quiet']) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed['stable'] is True and printed['metrics']['max_sinkage_m'] > 0
