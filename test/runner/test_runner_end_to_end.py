"""The runner with the real simulator and planners on headon2."""

import csv
import json
import re
import signal

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from runner_testing import HEADON, output, processes_with_token, start_runner, wait_for

SCHEMA_KEYS = {'scenario', 'method', 'eta', 'seed', 'mode', 'engine', 'ending', 'robots',
               'scripted_robots', 'success_rate',
               'collisions', 'min_separation', 'wall_contacts', 'min_wall_clearance',
               'makespan', 'mean_time_to_goal',
               'infeasible_fraction', 'min_achieved_eta', 'planner_ms', 'planner_cpu',
               'deadline_misses', 'sim_time', 'wall_time'}


@pytest.fixture(scope='module')
def headon2_run(tmp_path_factory, module_runners):
    """Return the runner of one whole ROS run of headon2 and its output folder, once it ended."""
    folder = tmp_path_factory.mktemp('headon2_run')
    out = folder / 'out'
    runner = start_runner([HEADON, '--out', str(out)], folder)
    module_runners.append(runner)
    runner.wait(timeout=600)
    return runner, out


def test_headon2_both_arrive_without_contact(headon2_run):
    runner, out = headon2_run
    assert runner.returncode == 0, output(runner)
    assert processes_with_token(runner.token) == []
    recorded = json.loads((out / 'metrics.json').read_text())
    assert set(recorded) == SCHEMA_KEYS
    assert (recorded['scenario'], recorded['method'], recorded['eta'], recorded['seed'],
            recorded['mode']) == ('headon2', 'prvo', 0.8, 3, 'lockstep')
    assert recorded['success_rate'] == 1.0
    assert recorded['collisions'] == 0
    assert recorded['scripted_robots'] == []
    assert all(robot['arrived'] for robot in recorded['robots'].values())
    # Straight-line distance is 8 m, minus the 0.2 m tolerance.
    for robot in recorded['robots'].values():
        assert robot['path_length'] >= 7.8 - 1e-6
        assert 7.8 / 1.0 <= robot['time_to_goal'] <= recorded['makespan']
    assert recorded['planner_ms']['median'] > 0.0
    # The planner nodes' CPU per plan, and the plans' own share of it.
    assert recorded['planner_cpu']['node_ms']['median'] > 0.0
    assert 0.0 < recorded['planner_cpu']['plan_ms']['median'] <= recorded['planner_cpu'][
        'node_ms']['max']
    assert 0.0 < recorded['planner_cpu']['planning_share'] <= 1.0

    with open(out / 'trajectories.csv') as csv_file:
        rows = list(csv.DictReader(csv_file))
    positions = {}
    for row in rows:
        positions.setdefault(row['time'], {})[row['robot']] = (float(row['x']), float(row['y']))
    separation = min(np.hypot(*np.subtract(pair['robot_0'], pair['robot_1'])) - 0.6
                     for pair in positions.values())
    assert separation == pytest.approx(recorded['min_separation'], abs=1e-5)
    assert separation > 0.0
    last = positions[max(positions, key=float)]
    assert np.hypot(last['robot_0'][0] - 4.0, last['robot_0'][1]) <= 0.2
    assert np.hypot(last['robot_1'][0] + 4.0, last['robot_1'][1]) <= 0.2
    assert (out / 'trajectories.png').read_bytes()[:4] == b'\x89PNG'
    stdout = runner.out_path.read_text()
    assert 'headon2' in stdout and str(out) in stdout
    # Every robot has the command answering its state at every step but perhaps the last.
    times = sorted({row['time'] for row in rows}, key=float)
    assert times[0] == '0'
    unanswered = {row['time'] for row in rows if row['cmd_vx'] == '' or row['cmd_vy'] == ''}
    assert unanswered <= {times[-1]}, sorted(unanswered, key=float)[:5]


def test_identical_lockstep_runs_record_identical_trajectories(headon2_run, tmp_path, runners):
    # The end is the step at which everyone has been home for the settle time, not the wall
    # time at which the runner noticed it. The second run writes no bag and no animation: what
    # the runner records is the same without them.
    first, first_out = headon2_run
    assert first.returncode == 0, output(first)
    runner = start_runner([HEADON, '--out', str(tmp_path / 'second'), '--quiet', '--no-bag',
                           '--no-animation'], tmp_path, label='second')
    runners.append(runner)
    assert runner.wait(timeout=300) == 0, output(runner)
    assert ((tmp_path / 'second' / 'trajectories.csv').read_bytes()
            == (first_out / 'trajectories.csv').read_bytes())


def test_sigint_during_a_real_run_leaves_no_process(tmp_path, runners):
    # A long scenario: the run must still be going when the signal comes, however fast.
    long_run = tmp_path / 'long.yaml'
    text = open(HEADON).read().replace('duration: 30.0', 'duration: 100000.0')
    text = text.replace('goal: [4.0, 0.0]', 'goal: [400.0, 0.0]')
    long_run.write_text(text.replace('goal: [-4.0, 0.0]', 'goal: [-400.0, 0.0]'))
    runner = start_runner([str(long_run), '--out', str(tmp_path / 'out')], tmp_path)
    runners.append(runner)
    # Progress lines come once every robot's ground truth is heard; a second of simulated time
    # later every planner has planned and reported (the first line alone came, at times, before
    # any diagnostics reached the bag).
    wait_for(lambda: _latest_sim_time(runner.err_path.read_text()) >= 1.0, 120,
             'a second of the run')
    runner.send_signal(signal.SIGINT)
    assert runner.wait(timeout=60) == 128 + signal.SIGINT
    assert processes_with_token(runner.token) == []
    recorded = json.loads((tmp_path / 'out' / 'metrics.json').read_text())
    assert recorded['failure'] == 'interrupted by SIGINT'
    assert recorded['sim_time'] >= 0.0
    # The bag keeps everything recorded up to the signal: each robot's ground truth at every
    # step of the CSV, from t_0, and each command the CSV has.
    with open(tmp_path / 'out' / 'trajectories.csv') as csv_file:
        rows = list(csv.DictReader(csv_file))
    with AnyReader([tmp_path / 'out' / 'bag']) as reader:
        stamps = {connection.topic: [] for connection in reader.connections}
        for connection, timestamp, _ in reader.messages():
            stamps[connection.topic].append(round(timestamp * 1e-6))
    assert rows and min(float(row['time']) for row in rows) == 0.0
    for robot in ('robot_0', 'robot_1'):
        robot_rows = [row for row in rows if row['robot'] == robot]
        times_ms = {round(float(row['time']) * 1e3) for row in robot_rows}
        commanded_ms = {round(float(row['time']) * 1e3) for row in robot_rows if row['cmd_vx']}
        assert times_ms <= set(stamps[f'/{robot}/ground_truth'])
        assert commanded_ms <= set(stamps[f'/{robot}/cmd_vel'])
    assert stamps['/clock'] and stamps['/diagnostics']


def _latest_sim_time(progress):
    """Return the simulated time [s] of the last progress line in PROGRESS, -1 before any."""
    times = re.findall(r'sim +([0-9.]+)/', progress)
    return float(times[-1]) if times else -1.0
