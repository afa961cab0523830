"""The crowd benchmark's generator and measures, against hand-computed values."""

import itertools
import math

import numpy as np
import pytest

from prvo_planner import stalls
from prvo_planner.parameters import DEFAULTS
from prvo_sim.bench import crowds as bench_crowds
from prvo_sim.bench import team as bench_team
from prvo_sim.bench.crowds import (
    arrival_times,
    contact_count,
    min_separation,
    path_ratio,
    random_team_document,
    run_row,
)
from prvo_sim.bench.engine import table
from prvo_sim.engine import InProcessTeam, StepRecord
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import find_scenario, load_scenario


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
    # Every document plans with the planner's defaults of eta, certificate and risk.
    defaults = {name: DEFAULTS[name] for name in ('eta', 'certificate', 'risk')}
    assert runs[-1][1] == {**random_team_document(0), 'planner': defaults}
    single = bench_crowds.planned_runs(bench_crowds.build_parser().parse_args(
        ['--circles', '8', '--teams', '0', '--no-fallback-circle']))
    assert single == [('circle8 r=4', {**bench_crowds.crowd_circle_document(8, 4.0),
                                       'planner': defaults}, 'prvo')]


def test_a_bad_seed_count_is_refused_with_its_value(capsys):
    assert bench_crowds.main(['--seeds', '0', '--no-peers']) == 2
    assert '--seeds: 0 is not a count' in capsys.readouterr().err


def test_eta_certificate_and_risk_apply_to_circles_and_teams_not_the_fallback_circle(capsys):
    runs = bench_crowds.planned_runs(bench_crowds.build_parser().parse_args(
        ['--circles', '24', '--teams', '1', '--sweep', '1', '--eta', '0.6', '--certificate',
         'cantelli', '--risk', 'joint']))
    circle, team, sweep, fallback = runs
    chosen = {'eta': 0.6, 'certificate': 'cantelli', 'risk': 'joint'}
    assert circle[0] == 'circle24 r=6 eta 0.6 cantelli joint' and circle[1]['planner'] == chosen
    assert team[0] == 'team0 N=14 eta 0.6 cantelli joint' and team[1]['planner'] == chosen
    assert sweep[1]['planner'] == chosen
    # Everything else of the documents is as without the options.
    assert circle[1] == {**bench_crowds.crowd_circle_document(24, 6.0), 'planner': chosen}
    assert fallback[2] == 'rvo' and fallback[1] == bench_crowds.crowd_circle_document(
        20, 5.0, noise_std=0.0)
    for bad in ('1.0', '0', '-0.2'):
        assert bench_crowds.main(['--eta', bad, '--no-peers']) == 2
        assert f'--eta: {float(bad)} is not a probability in (0, 1)' in capsys.readouterr().err


class _StandingTeam:
    """A team whose robots made no plan: what the monitor reads of a team, nothing more."""

    def __init__(self, count):
        self.last_commands = (None,) * count


def _steps(positions, commands, dt=0.5):
    """StepRecords of positions (T, N, 2) and commands (T, N, 2), DT apart."""
    velocities = np.zeros_like(positions)
    return [StepRecord(time=index * dt, states=np.concatenate([positions[index],
                                                               velocities[index]], axis=1),
                       commands=commands[index], plan_ms=np.zeros(positions.shape[1]),
                       contacts=()) for index in range(positions.shape[0])]


def _two_robot_scenario(tmp_path):
    document = {'name': 'stall', 'seed': 1, 'dt': 0.5, 'duration': 60.0, 'goal_tolerance': 0.2,
                'robots': [{'name': 'mover', 'start': [0.0, 0.0], 'goal': [20.0, 0.0],
                            'radius': 0.3, 'max_speed': 1.0},
                           {'name': 'dancer', 'start': [0.0, 5.0], 'goal': [10.0, 5.0],
                            'radius': 0.3, 'max_speed': 1.0}]}
    return bench_team.write_scenario(document, tmp_path / 'stall.yaml')


def test_the_stall_monitor_reports_a_robot_that_gains_too_little_once_per_stall(tmp_path):
    scenario = _two_robot_scenario(tmp_path)
    times = np.arange(0.0, 40.01, 0.5)
    # The mover drives at 1 m/s to its goal. The dancer drives at 1 m/s for 5 s, then goes back
    # and forth by 0.2 m every step (its command flipping) until t = 20 s, then drives on.
    mover = np.stack([np.minimum(times, 20.0), 0.0 * times], axis=1)
    dancer_x = np.where(times <= 5.0, times, np.where(
        times <= 20.0, 5.0 + 0.2 * (np.round((times - 5.0) / 0.5) % 2),
        np.minimum(5.0 + (times - 20.0), 10.0)))
    dancer = np.stack([dancer_x, 5.0 + 0.0 * times], axis=1)
    positions = np.stack([mover, dancer], axis=1)
    flips = np.where(np.round(times / 0.5) % 2 == 0, 0.4, -0.4)
    commands = np.stack([np.stack([0.0 * times + 1.0, 0.0 * times], axis=1),
                         np.stack([np.where((times > 5.0) & (times <= 20.0), flips, 1.0),
                                   0.0 * times], axis=1)], axis=1)
    monitor = bench_crowds.StallMonitor(scenario)
    team = _StandingTeam(2)
    for step in _steps(positions, commands):
        monitor(team, step)
    assert [stall['robot'] for stall in monitor.stalls] == ['dancer']
    stall = monitor.stalls[0]
    # The window 4.5 -> 14.5 s gains 0.7 m (x from 4.5 to 5.2 m); 5 -> 15 s none (5 to 5 m).
    assert stall['time_s'] == 15.0
    assert stall['position'] == [5.0, 5.0] and stall['distance_to_goal_m'] == 5.0
    assert stall['gained_m'] == 0.0
    # The window's 21 commands: 1 m/s at t = 5 s, then 20 alternating: 20 reversals.
    assert stall['command_reversals'] == 20
    assert stall['binding'] == []
    # Once it drives on again the stall is over; it is not reported again.
    assert not monitor.stalled


def test_a_robot_at_its_goal_does_not_stall_nor_one_stepping_aside_from_it(tmp_path):
    scenario = _two_robot_scenario(tmp_path)
    times = np.arange(0.0, 30.01, 0.5)
    goals = np.array([[20.0, 0.0], [10.0, 5.0]])
    positions = np.array(np.broadcast_to(goals, (times.size, 2, 2)) + np.array([0.1, 0.0]))
    # The second steps 0.25 m off its goal from t = 5 to 14 s (for a passer-by), then returns.
    positions[(times >= 5.0) & (times < 14.0), 1, 1] += 0.25
    monitor = bench_crowds.StallMonitor(scenario)
    for step in _steps(positions, np.zeros((times.size, 2, 2))):
        monitor(_StandingTeam(2), step)
    assert monitor.stalls == []


def test_a_robot_lingering_short_of_its_goal_stalls(tmp_path):
    # 0.4 m from its goal it need not gain 0.5 m, only reach the tolerance: it does not.
    scenario = _two_robot_scenario(tmp_path)
    times = np.arange(0.0, 30.01, 0.5)
    goals = np.array([[20.0, 0.0], [10.0, 5.0]])
    positions = np.array(np.broadcast_to(goals, (times.size, 2, 2)))
    positions[:, 1, 0] -= np.maximum(0.4 - 0.01 * times, 0.3)
    monitor = bench_crowds.StallMonitor(scenario)
    for step in _steps(positions, np.zeros((times.size, 2, 2))):
        monitor(_StandingTeam(2), step)
    assert [(stall['robot'], stall['time_s']) for stall in monitor.stalls] == [('dancer', 10.0)]


def test_binding_constraints_name_the_neighbours_nearest_their_limits():
    scenario = load_scenario(find_scenario('crossing4'))
    team = InProcessTeam(scenario, [planner_values(robot, scenario, 'prvo', None)
                                    for robot in scenario.robots])
    for _ in range(30):
        step = team.do_step()
    binding = bench_crowds.binding_constraints(team, 0)
    names = [robot.name for robot in scenario.robots]
    assert binding and len(binding) <= stalls.BINDING_COUNT
    bounds = [item['bound'] for item in binding]
    assert bounds == sorted(bounds)
    result = team.last_commands[0].result
    assert bounds[0] == round(float(min(result.neighbour_bounds)), 4)
    radii = {robot.name: robot.radius for robot in scenario.robots}
    for item in binding:
        other = names.index(item['neighbour'])
        assert other != 0
        # Between the beliefs' means: within the noise of the ground truth's gap.
        truth = (np.hypot(*(step.states[0, :2] - step.states[other, :2]))
                 - radii[names[0]] - radii[item['neighbour']])
        assert abs(item['gap_m'] - truth) < 0.3, (item, truth)


def test_sweep_teams_are_seeded_heterogeneous_teams_of_6_to_20():
    sizes = set()
    for index in range(50):
        document = bench_crowds.sweep_team_document(index)
        assert document == bench_crowds.sweep_team_document(index)
        count = len(document['robots'])
        assert 6 <= count <= 20
        sizes.add(count)
        # The random team of that size and index, under the sweep's seed and name.
        assert document['robots'] == random_team_document(
            index, count, bench_crowds.SWEEP_SEED)['robots']
    assert len({bench_crowds.sweep_team_document(index)['name'] for index in range(50)}) == 50
    assert len(sizes) >= 10


def test_a_run_row_has_the_stall_columns_of_the_planners_rule(tmp_path):
    scenario = _two_robot_scenario(tmp_path)
    row = bench_crowds.prvo_run('two', scenario, 'prvo')
    assert row['all_arrived'] and row['stalls'] == len(row['stall_reports']) == 0
    assert row['longest_stall_s'] == 0.0
    # Driving at up to 1 m/s, 0.5 s apart: near one spot only while slowing into its goal.
    assert 0.0 <= row['longest_dwell_s'] < 2.0
    heading = table([row], bench_crowds.COLUMNS).splitlines()[0]
    assert 'longest stall s' in heading and 'longest near one spot s' in heading
