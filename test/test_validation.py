"""`rft-sim validate`: the trend checks and the report on synthetic results (fast), the CLI
wiring, and (slow) a real quick validation run."""
import dataclasses

import pytest

from rft_sim_ros.cli import build_parser, main
from rft_sim_ros.validation import Results, report, trends
from rft_sim_ros.validation.cases import QUICK, Case

SETTINGS = dataclasses.replace(QUICK, leg_zetas=(3.75,), hexapod_zetas=(0.1, 0.5, 3.75))
SHAPES = ('flat', 'open_c', 'closed_c')


def synthetic(rail=None, torque_fast=2.4, speed_peak_kg=1.0, sink_exponent=1 / 3,
              paper_rail=None, paper_speed_peak_kg=3.0):
    """Results shaped like a quick run, with chosen numbers; the authors' loop's runs are
    `paper_rail` (default: the paper's ordering) and a hexapod fastest at
    `paper_speed_peak_kg` at zeta 3.75."""
    rail = rail or {'flat': 0.10, 'open_c': 0.08, 'closed_c': 0.12}
    paper_rail = paper_rail or {'flat': 0.10, 'open_c': 0.07, 'closed_c': 0.13}
    torque = {v: Case('rotating_intruder', {}, metrics={
        'peak_torque_increase_Nm': 2.4 if v < 2 else torque_fast, 'peak_sand_torque_Nm': 2.4,
        'angle_at_peak_deg': 55.0, 'max_sinkage_m': 0.055}) for v in SETTINGS.speeds}
    depths = {d: Case('rotating_intruder', {}, metrics={'peak_torque_increase_Nm': t})
              for d, t in ((0.005, 0.03), (0.0075, 0.06), (0.01, 0.1))}
    rails = {(s, v): Case(f'rail_{s}', {}, metrics={'carriage_displacement_m': rail[s]})
             for s in SHAPES for v in SETTINGS.speeds}
    legs = {3.75: Case('articulated_leg', {}, metrics={
        'carriage_displacement_per_step_m': 0.13, 'carriage_displacement_step_1_m': 0.13,
        'carriage_displacement_step_2_m': 0.13, 'carriage_displacement_step_3_m': 0.13,
        'stroke_m': 0.15, 'max_foot_sinkage_m': 0.03, 'peak_servo_torque_Nm': 3.0})}
    hexapod = {}
    for z in (0.1, 0.5, 3.75, 5.0):
        for p in (0.0, 1.0, 2.277):
            walked = 0.34 if z >= 0.5 else 0.03
            speed = walked / 5 * (1.02 if p == speed_peak_kg and z == 3.75 else 1.0)
            hexapod[z, p] = Case('hexapod', {}, metrics={
                'forward_distance_m': walked, 'mean_speed_mps': speed - 0.001 * p,
                'mean_sinkage_m': 0.07 * (3.75 / z) ** sink_exponent * (1 + 0.03 * p),
                'backward_fraction': 0.001, 'settled_base_height_m': 0.09,
                'total_mass_kg': 4.04 + p})
    rails_paper = {(s, v): Case(f'rail_{s}', {}, metrics={
        'carriage_displacement_m': paper_rail[s]}) for s in SHAPES for v in SETTINGS.speeds}
    hexapod_paper = {(z, p): Case('hexapod', {}, metrics={
        **hexapod[z, p].metrics, 'backward_fraction': 0.25,
        'mean_speed_mps': 0.02 + (0.001 if p == paper_speed_peak_kg and z == 3.75 else 0.0)})
        for z in SETTINGS.speed_zetas for p in SETTINGS.speed_payloads}
    return Results(settings=SETTINGS, torque=torque, depths=depths, rails=rails, legs=legs,
                   hexapod=hexapod, rails_paper=rails_paper, hexapod_paper=hexapod_paper,
                   hexapod_ema=hexapod[3.75, 0.0], trends=[], plots=[],
                   date='2026-01-01', machine='test', wall_s=1.0, case_count=1)


def test_trends_hold_on_results_that_show_them():
    held = trends.check(SETTINGS, *(getattr(synthetic(), k) for k in ('torque', 'rails',
                                                                       'hexapod')))
    assert len(held) == 7 and all(t.held for t in held), [t.name for t in held if not t.held]


@pytest.mark.parametrize('changes, broken', [
    ({'torque_fast': 2.7}, 'Intrusion torque'),
    ({'rail': {'flat': 0.10, 'open_c': 0.08, 'closed_c': 0.09}}, 'Carriage progress'),
    ({'speed_peak_kg': 0.0}, 'Hexapod speed'),
    ({'sink_exponent': -0.1}, 'Hexapod sinkage'),
])
def test_each_trend_fails_when_the_numbers_do_not_show_it(changes, broken):
    failed = [t.name for t in trends.check(SETTINGS, *(getattr(synthetic(**changes), k)
                                                        for k in ('torque', 'rails', 'hexapod')))
              if not t.held]
    assert failed and all(name.startswith(broken) for name in failed)


def test_paper_loop_trends_are_checked_on_its_own_runs():
    results = synthetic(rail={'flat': 0.10, 'open_c': 0.11, 'closed_c': 0.13})
    exact = trends.check(SETTINGS, results.torque, results.rails, results.hexapod)
    loop = trends.check_paper_loop(SETTINGS, results.rails_paper, results.hexapod_paper)
    assert not next(t for t in exact if t.name.startswith('Carriage progress')).held
    assert [t.held for t in loop] == [True, True, False]  # ordering, open C least; no optimum
    assert all(t.name.endswith("(the authors' loop)") for t in loop)
    peaked = synthetic(paper_speed_peak_kg=1.0)
    assert trends.check_paper_loop(SETTINGS, peaked.rails_paper, peaked.hexapod_paper)[2].held


def test_report_puts_our_figures_beside_the_papers_and_explains_differences(tmp_path):
    results = synthetic(rail={'flat': 0.10, 'open_c': 0.11, 'closed_c': 0.13})
    results.trends = (trends.check(SETTINGS, results.torque, results.rails, results.hexapod)
                      + trends.check_paper_loop(SETTINGS, results.rails_paper,
                                                results.hexapod_paper))
    path = tmp_path / 'report.md'
    report.write(path, results)
    text = path.read_text()
    assert ('| Open C progress vs flat, 0.5 / 1 / 2 rad/s | +10 % / +10 % / +10 % | -25 % '
            '| -53 % |') in text
    assert ("| Open C progress vs flat with the authors' loop (1 ms), 0.5 / 1 / 2 rad/s "
            '| -30 % / -30 % / -30 % | -25 % | -53 % |') in text
    assert "| Carriage progress closed C > flat > open C at every speed (the authors' loop) " \
           '|' in text
    assert 'the rocking comes with their loop (its lag' in text  # 0.25 against 0.001
    assert '| Carriage progress closed C > flat > open C at every speed |' in text
    assert '**not held**' in text and '**held**' in text
    assert 'x44' in text  # 2.4 N m against the paper's 0.055 N m
    assert 'about 0.7 cm of tip immersion' in text  # interpolated where 0.055 N m falls
    assert "the same force law does not put the open C behind flat" in text
    assert "the open C progresses -30 %, -30 %, -30 % against flat" in text


def test_vertical_plate_torque_is_the_rft_integral():
    # zeta alpha_x w integral_h^L (r - h) r dr, for h = 0: zeta 0.37 w L^3 / 3
    assert report.vertical_plate_torque(1.0, 0.02, 0.0, 0.06) == pytest.approx(
        1e6 * 0.37 * 0.02 * 0.06 ** 3 / 3, rel=1e-3)


def test_cli_validate_writes_the_committed_report_only_when_told():
    args = build_parser().parse_args(['validate'])
    assert args.out is None and not args.quick  # a fresh runs/validate-<time> (test_cli.py)
    assert build_parser().parse_args(['validate', '--quick', '--out', 'validation']).quick


@pytest.mark.slow
def test_quick_validation_writes_the_report_and_plots(tmp_path, capsys):
    assert main(['validate', '--quick', '--out', str(tmp_path)]) == 0
    text = (tmp_path / 'report.md').read_text()
    assert '## Trends' in text and (tmp_path / 'results.json').is_file()
    assert len(list(tmp_path.glob('*.png'))) == 7
    assert "## Trends" in text and "(the authors' loop)" in text
    assert 'Intrusion torque independent of rotation speed' in capsys.readouterr().out
