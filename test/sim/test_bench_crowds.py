"""The crowd benchmark's generator and measures, against hand-computed values."""

import itertools
import math

import numpy as np
import pytest

from prvo_sim import bench_crowds
from prvo_sim.bench_crowds import (
    arrival_times,
    contact_count,
    min_separation,
    path_ratio,
    random_team_document,
    run_row,
)


def test_random_teams_are_seeded_within_their_ranges_and_spaced():
    for index in range(4):
        document = random_team_document(index)
        assert document == random_team_document(index)
        robots = document['robots']
        assert len(robots) == 14
        half_side = 1.0 + 0.45 * 14
        for robot in robots:
            assert 0.2 <= robot['radius'] <= 0.45 and 0.6 <= robot['max_speed'] <= 1.2
            assert max(map(abs, robot['start'] + robot['goal'])) <= half_side
            # Rounding to 0.1 mm may bring points that close.
            assert math.dist(robot['start'], robot['goal']) >= 0.4 * half_side - 1e-3
        for first, second in itertools.combinations(robots, 2):
            assert math.dist(first['start'], second['start']) >= 0.4 * half_side - 1e-3
            assert math.dist(first['goal'], second['goal']) >= 0.4 * half_side - 1e-3
    assert random_team_document(0)['robots'] != random_team_document(1)['robots']


def test_measures_of_a_hand_made_trajectory():
    # Two robots of radii 0.3 and 0.2: robot 0 along the x axis from 0 to 2 m at 1 m/s, robot 1
    # standing at (1.4, 0) but 1 m off it at t = 0.5 s.
    times = np.arange(0.0, 3.01, 0.5)
    first = np.minimum(times, 2.0)
    positions = np.stack([np.stack([first, 0.0 * times], axis=1),
                          np.stack([1.4 + 0.0 * times, np.where(times == 0.5, 1.0, 0.0)],
                                   axis=1)], axis=1)
    goals = np.array([[2.0, 0.0], [1.4, 0.0]])
    radii = np.array([0.3, 0.2])
    np.testing.assert_allclose(arrival_times(times, positions, goals, 0.2), [2.0, 1.0])
    # Closest at t = 1.5 s: 0.1 m apart between centres, 0.5 m of radii.
    assert min_separation(positions, radii) == pytest.approx(-0.4)
    # In contact at t = 1.0 s (0.4 m apart) and 1.5 s, apart again from 2.0 s: one contact.
    assert contact_count(positions, radii) == 1
    row = run_row('hand', 'prvo', times, positions, positions[0], goals, radii,
                  np.array([1.0, 1.0]), 0.2)
    # Straight-line times 2 s and 0 s: makespan 2 s over the longest, mean 1.5 s over 1 s.
    assert row['makespan_s'] == 2.0 and row['makespan_ratio'] == 1.0
    assert row['mean_time_ratio'] == 1.5 and row['all_arrived']
    # Up to its arrival robot 0 drove its 2 m; robot 1, with no way to go, 1 m off and back.
    assert row['path_ratio'] == 2.0


def test_a_robot_that_never_stays_has_no_arrival():
    times = np.array([0.0, 1.0, 2.0])
    positions = np.array([[[0.0, 0.0]], [[1.0, 0.0]], [[0.0, 0.0]]])
    arrivals = arrival_times(times, positions, np.array([[1.0, 0.0]]), 0.2)
    assert arrivals[0] == math.inf
    # Its whole path counts: 2 m against a 1 m straight line.
    assert path_ratio(times, positions, positions[0], np.array([[1.0, 0.0]]), arrivals) == 2.0


def test_bad_team_sizes_are_refused_with_their_value(capsys):
    assert bench_crowds.main(['--circles', '1', '--no-peers']) == 2
    assert '--circles: 1 is not a team' in capsys.readouterr().err
    assert bench_crowds.main(['--teams', '-1', '--no-peers']) == 2
    assert '--teams: -1 is negative' in capsys.readouterr().err


def test_circles_repeat_over_consecutive_seeds():
    options = bench_crowds.build_parser().parse_args(
        ['--circles', '8', '24', '--seeds', '3', '--teams', '1', '--no-fallback-circle'])
    runs = bench_crowds.planned_runs(options)
    seed = bench_crowds.crowd_circle_document(8, 4.0)['seed']
    circles = [(label, document['seed'], len(document['robots']))
               for label, document, _ in runs[:-1]]
    assert circles == [(f'circle{count} r={radius} seed {seed + offset}', seed + offset, count)
                       for count, radius in ((8, 4), (24, 6)) for offset in range(3)]
    # Each seed's scenario is a file of its own; the team keeps its seed.
    assert len({document['name'] for _, document, _ in runs}) == len(runs)
    assert runs[-1][1] == random_team_document(0)
    single = bench_crowds.planned_runs(bench_crowds.build_parser().parse_args(
        ['--circles', '8', '--teams', '0', '--no-fallback-circle']))
    assert single == [('circle8 r=4', bench_crowds.crowd_circle_document(8, 4.0), 'prvo')]


def test_a_bad_seed_count_is_refused_with_its_value(capsys):
    assert bench_crowds.main(['--seeds', '0', '--no-peers']) == 2
    assert '--seeds: 0 is not a count' in capsys.readouterr().err


def test_eta_applies_to_circles_and_teams_not_the_fallback_circle(capsys):
    runs = bench_crowds.planned_runs(bench_crowds.build_parser().parse_args(
        ['--circles', '24', '--teams', '1', '--eta', '0.6']))
    circle, team, fallback = runs
    assert circle[0] == 'circle24 r=6 eta 0.6' and circle[1]['planner']['eta'] == 0.6
    assert team[0] == 'team0 N=14 eta 0.6' and team[1]['planner']['eta'] == 0.6
    # Everything else of the documents is as without --eta.
    circle[1]['planner']['eta'] = 0.8
    assert circle[1] == bench_crowds.crowd_circle_document(24, 6.0)
    assert fallback[2] == 'rvo' and fallback[1] == bench_crowds.crowd_circle_document(
        20, 5.0, noise_std=0.0)
    for bad in ('1.0', '0', '-0.2'):
        assert bench_crowds.main(['--eta', bad, '--no-peers']) == 2
        assert f'--eta: {float(bad)} is not a probability in (0, 1)' in capsys.readouterr().err
