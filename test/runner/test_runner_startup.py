"""Start-up order: planners first, the simulator only once the recorder hears every planner.

The fake planners create their publishers only when the test opens a gate, so the state "every
planner runs, none publishes yet" lasts as long as the test wants: the simulator must not be
started in it, and must be started, told to wait for the recorder, once the gate opens.
"""

import os
import re
import shlex
import signal

from runner_testing import (
    FAKE_CHILD,
    HEADON,
    processes_with_token,
    runner_domain,
    start_runner,
    wait_for,
)
import yaml


def log_text(out, label):
    path = out / 'logs' / f'{label}.log'
    return path.read_text() if path.exists() else ''


def test_simulator_starts_after_every_cmd_vel_is_matched_and_waits_for_the_recorder(
        tmp_path, runners):
    out = tmp_path / 'out'
    gate = tmp_path / 'gate'
    runner = start_runner(
        [HEADON, '--out', str(out), '--sim-command', f'{FAKE_CHILD} run',
         '--planner-command', f'{FAKE_CHILD} planner'], tmp_path,
        env={'PRVO_FAKE_PLANNER_GATE': str(gate)})
    runners.append(runner)
    domain_id = runner_domain(runner)
    wait_for(lambda: all('ready' in log_text(out, f'planner_robot_{index}')
                         for index in (0, 1)), 60, 'both planners running')
    # Both planners are up without a cmd_vel publisher: nothing can have matched.
    assert not (out / 'logs' / 'sim.log').exists()
    # Two planners and their grandchildren, the watchdog and the recorder's listener (which
    # may still be starting when the planners are up: the CI run that counted 5).
    wait_for(lambda: len(processes_with_token(runner.token, exclude={runner.pid})) == 6, 60,
             'six processes of the run')
    assert not (out / 'logs' / 'sim.log').exists()
    gate.touch()
    sim_log = wait_for(lambda: log_text(out, 'sim'), 60, 'the simulator starting')
    assert all('publishing' in log_text(out, f'planner_robot_{index}') for index in (0, 1))
    sim_argv = shlex.split(sim_log.splitlines()[0].removeprefix('$ '))
    observers = [yaml.safe_load(argument.removeprefix('observers:='))
                 for argument in sim_argv if argument.startswith('observers:=')]
    assert len(observers) == 1 and len(observers[0]) == 1, sim_argv
    # Unique to the run: the recorder's name holds the runner's domain and pid.
    assert re.fullmatch(rf'/prvo_run_recorder_d{domain_id}_p{runner.pid}_\d+', observers[0][0])
    runner.send_signal(signal.SIGINT)
    assert runner.wait(timeout=30) == 128 + signal.SIGINT
    assert os.path.exists(out / 'metrics.json')
