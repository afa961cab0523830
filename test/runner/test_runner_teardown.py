"""Every run ends and keeps what it measured: results first, a bounded teardown, live signals."""

import json
import os
import pathlib
import re
import resource
import signal
import time

import pytest
from runner_testing import (
    FAKE_CHILD,
    FAKE_RUN_DESCENDANTS,
    HEADON,
    listener_pids,
    output,
    processes_with_token,
    start_runner,
    wait_for,
)
import yaml

from prvo_sim.bench.crowds import crowd_circle_document
from prvo_sim.runner import inprocess
from prvo_sim.runner.command_line import build_parser
from prvo_sim.runner.processes import SHUTDOWN_GRACE, package_command
from prvo_sim.runner.session import RunSpec
from prvo_sim.scenario import load_scenario

FAKE_TEAM = ['--sim-command', f'{FAKE_CHILD} run', '--planner-command', f'{FAKE_CHILD} planner']
RESULTS = ('metrics.json', 'trajectories.csv')
PROGRESS = re.compile(r'sim\s+([0-9.]+)/')


def start_fake_run(tmp_path, runners, *extra):
    runner = start_runner([HEADON, '--out', str(tmp_path / 'out'), *FAKE_TEAM, *extra], tmp_path)
    runners.append(runner)
    wait_for(lambda: len(processes_with_token(runner.token, exclude={runner.pid}))
             == FAKE_RUN_DESCENDANTS, 60, 'every descendant running')
    return runner


def far_headon(tmp_path, duration=400.0):
    """Return a headon2 whose robots travel 300 m, in a run of at most DURATION s."""
    document = yaml.safe_load(pathlib.Path(HEADON).read_text())
    document['duration'] = duration
    for robot, x in zip(document['robots'], (-150.0, 150.0), strict=True):
        robot['start'], robot['goal'] = [x, 0.0], [-x, 0.0]
    path = tmp_path / 'far_headon.yaml'
    path.write_text(yaml.safe_dump(document))
    return path


def sim_time_reported(runner):
    """Return the newest sim time on the runner's progress line, 0 before the first."""
    times = PROGRESS.findall(runner.err_path.read_text())
    return float(times[-1]) if times else 0.0


def test_a_listener_that_stops_answering_costs_nothing_recorded(tmp_path, runners):
    # Stand-in for Fast DDS deadlocking in the participant's process: it never runs again.
    runner = start_fake_run(tmp_path, runners)
    (listener,) = listener_pids(runner.token)
    os.kill(listener, signal.SIGSTOP)
    runner.send_signal(signal.SIGINT)
    assert runner.wait(timeout=60) == 128 + signal.SIGINT, output(runner)
    recorded = json.loads((tmp_path / 'out' / 'metrics.json').read_text())
    assert recorded['failure'] == 'interrupted by SIGINT'
    assert (tmp_path / 'out' / 'trajectories.csv').is_file()
    assert processes_with_token(runner.token) == []


def test_a_second_signal_in_the_teardown_cuts_the_childrens_grace(tmp_path, runners):
    # A planner that ignores SIGINT holds the teardown for SHUTDOWN_GRACE s, unless the user
    # insists: the results are on disk before the runner waits for any child.
    runner = start_runner([HEADON, '--out', str(tmp_path / 'out'), '--sim-command',
                           f'{FAKE_CHILD} run', '--planner-command', f'{FAKE_CHILD} stubborn'],
                          tmp_path)
    runners.append(runner)
    wait_for(lambda: all('ready' in path.read_text()
                         for path in (tmp_path / 'out' / 'logs').glob('planner_*.log'))
             and len(list((tmp_path / 'out' / 'logs').glob('planner_*.log'))) == 2,
             60, 'the stubborn planners starting')
    interrupted_at = time.monotonic()
    runner.send_signal(signal.SIGINT)
    wait_for(lambda: (tmp_path / 'out' / 'metrics.json').is_file(), 30,
             'the results written while the children are still stopping')
    assert runner.poll() is None
    runner.send_signal(signal.SIGTERM)
    assert runner.wait(timeout=60) == 128 + signal.SIGINT, output(runner)
    assert time.monotonic() - interrupted_at < SHUTDOWN_GRACE
    assert processes_with_token(runner.token) == []


def test_a_double_ctrl_c_after_a_run_keeps_its_results(tmp_path, runners):
    out = tmp_path / 'out'
    runner = start_runner([str(far_headon(tmp_path)), '--out', str(out)], tmp_path)
    runners.append(runner)
    # The progress line is printed every 5 s of wall time off a terminal.
    wait_for(lambda: sim_time_reported(runner) >= 2.0, 300, 'two seconds of the run')
    runner.send_signal(signal.SIGINT)
    time.sleep(0.3)
    runner.send_signal(signal.SIGINT)
    assert runner.wait(timeout=60) == 128 + signal.SIGINT, output(runner)
    recorded = json.loads((out / 'metrics.json').read_text())
    assert recorded['ending'] == 'interrupted' and recorded['sim_time'] >= 2.0
    rows = (out / 'trajectories.csv').read_text().splitlines()
    assert len(rows) > 2 * 20
    assert processes_with_token(runner.token) == []


def circle24(tmp_path):
    """Write the README's 24-robot crowd circle (6 m, noise 0.05); return its path."""
    path = tmp_path / 'circle24.yaml'
    path.write_text(yaml.safe_dump(crowd_circle_document(24, 6.0, 0.05)))
    return path


def test_a_24_robot_lockstep_ros_run_ends_with_its_results(tmp_path, runners):
    out = tmp_path / 'out'
    # Niced (every child inherits it): its 26 processes would otherwise take most of both cores
    # from the test running beside it on the other worker, ten times slower then (CI: 1.1 s
    # in-process runs took 15-18 s). Lockstep, its outcome does not depend on its pace.
    runner = start_runner([str(circle24(tmp_path)), '--out', str(out), '--quiet'], tmp_path,
                          preexec_fn=lambda: os.nice(10))
    runners.append(runner)
    assert runner.wait(timeout=1500) == 0, output(runner)
    recorded = json.loads((out / 'metrics.json').read_text())
    assert recorded['ending'] == 'arrived' and recorded['success_rate'] == 1.0
    for name in (*RESULTS, 'trajectories.png', 'trajectories.gif', 'bag/metadata.yaml'):
        assert (out / name).is_file(), name
    assert processes_with_token(runner.token) == []


def test_the_inprocess_time_limit_holds_within_a_step_that_never_ends(tmp_path, monkeypatch):
    def hang(_team, advance=True):
        time.sleep(3600)

    monkeypatch.setattr(inprocess.InProcessTeam, 'do_step', hang)
    scenario = load_scenario(HEADON)
    options = build_parser().parse_args([HEADON, '--engine', 'inprocess', '--timeout', '1',
                                         '--quiet'])
    result = inprocess.run_inprocess(RunSpec(options, scenario, 0.8, scenario.seed,
                                             tmp_path / 'out'))
    assert result.failure == 'timed out after 1 s of wall time'
    assert json.loads((tmp_path / 'out' / 'metrics.json').read_text())['ending'] == 'failed'


def limit_file_size(limit_bytes):
    """Return a preexec function: files larger than LIMIT_BYTES fail to write (a full disk)."""
    def preexec():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))
    return preexec


def test_a_full_disk_costs_the_views_not_the_results(tmp_path, runners):
    out = tmp_path / 'out'
    # metrics.json and trajectories.csv fit, the plot, the bag and the GIF do not.
    runner = start_runner([HEADON, '--engine', 'inprocess', '--out', str(out), '--quiet'],
                          tmp_path, preexec_fn=limit_file_size(40_000))
    runners.append(runner)
    assert runner.wait(timeout=300) == 0, output(runner)
    errors = runner.err_path.read_text().strip().splitlines()
    assert 'Traceback' not in runner.err_path.read_text()
    assert sorted(line.split(':')[2].split()[0] for line in errors) == [
        'bag/', 'trajectories.gif', 'trajectories.png'], errors
    assert all(line.startswith('run_scenario: warning: ') for line in errors)
    assert sorted(path.name for path in out.iterdir()) == sorted(RESULTS)
    assert json.loads((out / 'metrics.json').read_text())['success_rate'] == 1.0
    assert 'outcome: 2/2 arrived' in runner.out_path.read_text()


@pytest.fixture(scope='module')
def short_far_run(tmp_path_factory, module_runners):
    """Return the ended runner of 2 s of a far head-on in process, and its output folder.

    Without env.sh (AMENT_PREFIX_PATH dropped) and under the umask 002: one run for the test of
    each. Two seconds write every file a whole run does (a run that reaches its duration
    completes).
    """
    folder = tmp_path_factory.mktemp('short_far_run')
    out = folder / 'out'
    runner = start_runner([str(far_headon(folder, duration=2.0)), '--engine', 'inprocess',
                           '--out', str(out), '--quiet'],
                          folder, preexec_fn=lambda: os.umask(0o002), drop=('AMENT_PREFIX_PATH',))
    module_runners.append(runner)
    runner.wait(timeout=300)
    return runner, out


def test_results_get_the_mode_of_the_umask(short_far_run):
    runner, out = short_far_run
    assert runner.returncode == 0, output(runner)
    for path in (*(out / name for name in (*RESULTS, 'trajectories.png', 'trajectories.gif')),
                 *(out / 'bag').iterdir()):
        assert path.stat().st_mode & 0o777 == 0o664, path
    assert (out / 'bag').stat().st_mode & 0o777 == 0o775


def test_a_second_run_into_the_same_folder_is_refused(tmp_path, runners):
    first = start_fake_run(tmp_path, runners)
    second = start_runner([HEADON, '--engine', 'inprocess', '--out', str(tmp_path / 'out')],
                          tmp_path, label='second')
    runners.append(second)
    assert second.wait(timeout=60) == 2
    error = second.err_path.read_text().strip().splitlines()
    assert len(error) == 1 and f'pid {first.pid}' in error[0] and '--out' in error[0], error
    assert first.poll() is None


def test_an_interrupted_sweep_summarises_the_seeds_it_ran(tmp_path, runners):
    out = tmp_path / 'sweep'
    runner = start_runner([str(far_headon(tmp_path, duration=10.0)), '--engine', 'inprocess',
                           '--out', str(out), '--seeds', '50', '--no-animation', '--no-bag'],
                          tmp_path)
    runners.append(runner)
    wait_for(lambda: len(list(out.glob('seed_*/metrics.json'))) >= 2, 300, 'two seeds run')
    runner.send_signal(signal.SIGINT)
    assert runner.wait(timeout=60) == 128 + signal.SIGINT, output(runner)
    summary = json.loads((out / 'summary.json').read_text())
    assert 2 <= len(summary['seeds']) < 50
    assert len(summary['runs']) == len(summary['seeds'])


@pytest.mark.parametrize('arguments', [['--seeds', '10000'],
                                       ['--seed', '2147483647', '--seeds', '2']])
def test_a_sweep_beyond_the_limits_is_refused(tmp_path, arguments, capsys):
    from prvo_sim.runner.command_line import main

    assert main([HEADON, '--engine', 'inprocess', '--out', str(tmp_path / 'out'),
                 *arguments]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and '--seeds' in lines[0], lines
    assert not (tmp_path / 'out').exists()


def test_the_runner_needs_no_env_sh(short_far_run):
    # The run reaches its duration and writes its bag without AMENT_PREFIX_PATH.
    runner, out = short_far_run
    assert runner.returncode == 0, output(runner)
    assert (out / 'bag' / 'metadata.yaml').is_file()


def test_the_ros_engine_finds_its_own_executables_without_the_ament_index(monkeypatch):
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    (command,) = package_command('prvo_sim', 'sim', 'prvo_sim.sim_node')
    assert command.endswith('/lib/prvo_sim/sim') and os.access(command, os.X_OK)


@pytest.mark.parametrize('engine', ['inprocess', 'ros'])
def test_a_run_reports_the_guarantee_its_plans_did_not_have(engine, tmp_path, runners):
    # At eta 0.9999 no velocity of a head-on encounter meets the constraint while the two are
    # within the horizon of each other (31% of the plans at 2 s): the run arrives without
    # contact on the fallback, and must not read as if the guarantee had held.
    out = tmp_path / 'out'
    runner = start_runner([HEADON, '--engine', engine, '--eta', '0.9999', '--out', str(out),
                           '--quiet', '--no-bag', '--no-animation'], tmp_path)
    runners.append(runner)
    assert runner.wait(timeout=300) == 0, output(runner)
    recorded = json.loads((out / 'metrics.json').read_text())
    assert recorded['infeasible_fraction'] > 0.2
    assert recorded['min_achieved_eta'] < 0.9
    for robot in recorded['robots'].values():
        assert robot['plans'] > 20 and robot['infeasible_fraction'] > 0.2
        assert recorded['min_achieved_eta'] <= robot['min_achieved_eta'] < 0.9999
    outcome = next(line for line in runner.out_path.read_text().splitlines()
                   if 'outcome:' in line)
    assert '% of plans infeasible (achieved eta down to ' in outcome, outcome
