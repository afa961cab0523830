"""Results: written only by a run that started children, atomically, as strict JSON."""

import dataclasses
import json
import math

import pytest
from runner_testing import FAKE_CHILD, HEADON, runner_domain, start_runner

from prvo_sim import run_scenario
from prvo_sim.runner.outputs import Ending, Recording, planner_cpu
from prvo_sim.scenario import load_scenario

FAKE_TEAM = ['--sim-command', f'{FAKE_CHILD} run', '--planner-command', f'{FAKE_CHILD} planner']
CRASHING_TEAM = ['--sim-command', f'{FAKE_CHILD} run',
                 '--planner-command', f'{FAKE_CHILD} crash']


def good_results(folder):
    """Leave a previous run's three results in FOLDER; return their contents."""
    folder.mkdir(parents=True)
    contents = {'metrics.json': b'{"success_rate": 1.0}\n',
                'trajectories.csv': b'time,robot\n', 'trajectories.png': b'\x89PNG old'}
    for name, data in contents.items():
        (folder / name).write_bytes(data)
    return contents


def test_refused_run_leaves_previous_results_untouched(tmp_path, runners, ros_domain):
    out = tmp_path / 'out'
    previous = good_results(out)
    # The test holds the claim on ros_domain: the runner must refuse it.
    runner = start_runner([HEADON, '--out', str(out), '--domain-id', str(ros_domain),
                           *FAKE_TEAM], tmp_path)
    runners.append(runner)
    assert runner.wait(timeout=60) == 2
    assert {path.name: path.read_bytes() for path in out.iterdir()} == previous


def test_failed_run_leaves_no_stale_plot_beside_its_metrics(tmp_path, runners):
    out = tmp_path / 'out'
    good_results(out)
    runner = start_runner([HEADON, '--out', str(out), *CRASHING_TEAM], tmp_path)
    runners.append(runner)
    runner_domain(runner)
    assert runner.wait(timeout=60) == 1
    recorded = json.loads((out / 'metrics.json').read_text())
    assert 'exited with code 3' in recorded['failure']
    assert not (out / 'trajectories.png').exists()
    assert (out / 'trajectories.csv').read_text().startswith('time,robot,x,y')
    assert sorted(path.name for path in out.iterdir()) == [
        'logs', 'metrics.json', 'trajectories.csv']


def test_metrics_json_is_strict_json(tmp_path):
    scenario = load_scenario(HEADON)
    options = run_scenario.build_parser().parse_args([HEADON])
    spec = run_scenario.RunSpec(options, scenario, None, scenario.seed, tmp_path)
    # No step recorded, but odd plan times.
    recording = dataclasses.replace(Recording.empty(2), plan_times_ms=(1.0, math.inf))
    run_scenario.write_outputs(spec, recording, Ending.FAILED, 'a failure', wall_time=math.nan)

    def refuse(constant):
        raise AssertionError(f'{constant} in metrics.json')

    recorded = json.loads((tmp_path / 'metrics.json').read_text(), parse_constant=refuse)
    assert recorded['planner_ms']['max'] is None
    assert recorded['planner_cpu'] == {'node_ms': {'median': None, 'p95': None, 'max': None},
                                       'plan_ms': {'median': None, 'p95': None, 'max': None},
                                       'planning_share': None}
    assert recorded['wall_time'] is None
    assert recorded['failure'] == 'a failure' and recorded['ending'] == 'failed'


def test_eta_is_per_robot_unless_given(tmp_path):
    scenario_path = tmp_path / 'mixed.yaml'
    text = open(HEADON).read()
    assert '  - name: robot_1\n' in text
    scenario_path.write_text(text.replace(
        '  - name: robot_1\n', '  - name: robot_1\n    planner: {eta: 0.5}\n', 1))
    scenario = load_scenario(scenario_path)
    first, second = scenario.robots
    assert run_scenario.planner_parameters(second, scenario, 'prvo', None)['eta'] == '0.5'
    assert run_scenario.planner_parameters(first, scenario, 'prvo', None)['eta'] == repr(
        float(first.planner.get('eta', run_scenario.DEFAULT_ETA)))
    assert run_scenario.planner_parameters(second, scenario, 'prvo', 0.9)['eta'] == '0.9'
    options = run_scenario.build_parser().parse_args([str(scenario_path)])
    assert run_scenario.run_eta(options, scenario) == [
        float(first.planner.get('eta', run_scenario.DEFAULT_ETA)), 0.5]
    options = run_scenario.build_parser().parse_args([str(scenario_path), '--eta', '0.7'])
    assert run_scenario.run_eta(options, scenario) == 0.7
    uniform = load_scenario(HEADON)
    assert run_scenario.run_eta(run_scenario.build_parser().parse_args([HEADON]),
                                uniform) == 0.8


def test_a_recording_with_missing_steps_or_commands_is_a_failure():
    dt_ns = 100_000_000
    complete = {name: {step * dt_ns: (0.0,) for step in range(5)}
                for name in ('robot_0', 'robot_1')}
    # Every command but the last step's (still being answered when the run ended).
    commands = {name: {step * dt_ns: (0.0,) for step in range(4)} for name in complete}
    names = list(complete)
    assert run_scenario.recording_gaps(complete, commands, names, 0.1, True) is None
    late_start = {**complete, 'robot_1': {stamp: value for stamp, value in
                                          complete['robot_1'].items() if stamp >= 2 * dt_ns}}
    gap = run_scenario.recording_gaps(late_start, commands, names, 0.1, True)
    assert 'robot_1' in gap and 'ground truth' in gap and 't = 0' in gap
    hole = {**complete, 'robot_0': {stamp: value for stamp, value in complete['robot_0'].items()
                                    if stamp != 3 * dt_ns}}
    gap = run_scenario.recording_gaps(hole, commands, names, 0.1, True)
    assert 'robot_0' in gap and 't = 0.3' in gap
    no_first_command = {**commands, 'robot_0': {stamp: value for stamp, value in
                                                commands['robot_0'].items() if stamp}}
    gap = run_scenario.recording_gaps(complete, no_first_command, names, 0.1, True)
    assert 'robot_0' in gap and 'command' in gap and 't = 0' in gap
    # In realtime a planner may miss a step's deadline: no command is not a recording fault.
    assert run_scenario.recording_gaps(complete, no_first_command, names, 0.1, False) is None
    assert 'no ground truth' in run_scenario.recording_gaps(
        {'robot_0': {}, 'robot_1': {}}, commands, names, 0.1, True)


def test_a_run_ended_at_a_step_needs_that_steps_answers_and_ignores_later_steps():
    dt_ns = 100_000_000
    # The team went on past the end (t = 0.3) until it was stopped.
    ground_truth = {name: {step * dt_ns: (0.0,) for step in range(6)}
                    for name in ('robot_0', 'robot_1')}
    names = list(ground_truth)
    up_to_the_end = {name: {step * dt_ns: (0.0,) for step in range(4)} for name in names}
    assert run_scenario.recording_gaps(ground_truth, up_to_the_end, names, 0.1, True,
                                       until=0.3) is None
    before_the_end = {name: {step * dt_ns: (0.0,) for step in range(3)} for name in names}
    gap = run_scenario.recording_gaps(ground_truth, before_the_end, names, 0.1, True,
                                      until=0.3)
    assert 'command' in gap and 't = 0.3' in gap


def test_the_planner_nodes_cpu_is_summarised_with_the_share_of_planning():
    summary = planner_cpu([(2.0, 10.0), (4.0, 10.0), (3.0, 40.0)])
    assert summary['node_ms'] == {'median': 10.0, 'p95': pytest.approx(37.0), 'max': 40.0}
    # numpy's linear p95 of (2, 3, 4): 3 + 0.9 (4 - 3).
    assert summary['plan_ms'] == {'median': 3.0, 'p95': pytest.approx(3.9), 'max': 4.0}
    assert summary['planning_share'] == pytest.approx(9.0 / 60.0)
