"""A run owns its ROS domain or refuses it; strangers on it are named, never merged."""

import json
import os
import signal

from rosgraph_msgs.msg import Clock
from runner_testing import (
    FAKE_CHILD,
    FAKE_RUN_DESCENDANTS,
    HEADON,
    free_domain,
    output,
    processes_with_token,
    runner_domain,
    start_runner,
    wait_for,
)

from prvo_sim import run_scenario
from prvo_sim.run_scenario import Recorder

FAKE_TEAM = ['--sim-command', f'{FAKE_CHILD} run', '--planner-command', f'{FAKE_CHILD} planner']


def start_fake_run(tmp_path, runners, *extra, label='runner', env=None):
    runner = start_runner([HEADON, '--out', str(tmp_path / label), *FAKE_TEAM, *extra],
                          tmp_path, label=label, env=env)
    runners.append(runner)
    return runner


def wait_until_running(runner):
    wait_for(lambda: len(processes_with_token(runner.token, exclude={runner.pid}))
             == FAKE_RUN_DESCENDANTS, 60, 'every descendant running')


def test_second_runner_on_a_held_domain_exits_2_naming_the_holder(tmp_path, runners,
                                                                  released_domain):
    first = start_fake_run(tmp_path, runners, '--domain-id', str(released_domain))
    assert runner_domain(first) == released_domain
    wait_until_running(first)
    second = start_fake_run(tmp_path, runners, '--domain-id', str(released_domain),
                            label='second')
    assert second.wait(timeout=60) == 2
    error = second.err_path.read_text().strip().splitlines()
    assert len(error) == 1, error
    assert f'ROS_DOMAIN_ID {released_domain}' in error[0] and f'pid {first.pid}' in error[0]
    assert 'prvo_sim.run_scenario' in error[0]
    assert not (tmp_path / 'second').exists()
    assert processes_with_token(second.token) == []
    assert first.poll() is None


def test_exported_domain_is_used_and_domain_id_option_wins(tmp_path, runners, released_domain):
    from_environment = start_fake_run(tmp_path, runners,
                                      env={'ROS_DOMAIN_ID': str(released_domain)})
    assert runner_domain(from_environment) == released_domain
    assert 'environment' in from_environment.out_path.read_text().splitlines()[0]
    wait_until_running(from_environment)
    # The option wins: the exported domain is held by the first runner, so taking it would fail.
    domain_for_option = free_domain()
    from_option = start_fake_run(tmp_path, runners, '--domain-id', str(domain_for_option),
                                 label='option', env={'ROS_DOMAIN_ID': str(released_domain)})
    assert runner_domain(from_option) == domain_for_option


def test_exported_domain_outside_the_range_is_bad_input(tmp_path, runners):
    runner = start_fake_run(tmp_path, runners, env={'ROS_DOMAIN_ID': '233'})
    assert runner.wait(timeout=60) == 2
    assert 'ROS_DOMAIN_ID' in runner.err_path.read_text() and '233' in output(runner)
    assert not (tmp_path / 'runner').exists()


def test_stranger_on_an_explicit_domain_refuses_the_run(tmp_path, runners, released_domain,
                                                        strangers):
    strangers(released_domain, '-r', '__ns:=/robot_0', '-r', '__node:=old_planner')
    runner = start_fake_run(tmp_path, runners, '--domain-id', str(released_domain))
    code = runner.wait(timeout=60)
    # Heard in the check before the run, it is refused (stderr) and nothing is started or
    # written. The check listens DOMAIN_CHECK_TIME of wall time: on a machine loaded enough that
    # discovery takes longer (it did in fresh-clone CIs), the stranger is heard once the run has
    # started, and the run stops as interfered with, its outcome (stdout) naming it. Either way
    # no run goes on.
    if code == 2:
        error = runner.err_path.read_text()
        assert not (tmp_path / 'runner').exists()
    else:
        error = runner.out_path.read_text()
        assert code == 1 and 'FAILED: processes this runner did not start publish' in error, error
    assert '/robot_0/old_planner' in error and '/robot_0/cmd_vel' in error, error
    assert processes_with_token(runner.token) == []


def test_automatic_choice_skips_a_domain_with_strangers():
    refused = []

    def vet(domain_id):
        if not refused:
            refused.append(domain_id)
            return f'node /stranger publishes on /chatter (ROS_DOMAIN_ID {domain_id})'
        return None

    with run_scenario.claimed_domain(None, vet=vet) as domain_id:
        assert refused and domain_id != refused[0]
        # The refused domain's claim was given back.
        with run_scenario.claimed_domain(refused[0]) as again:
            assert again == refused[0]


def test_domain_vetting_names_a_stray_node_and_its_topic(ros_domain, strangers):
    strangers(ros_domain, '-r', '__ns:=/robot_1', '-r', '__node:=stray')
    reason = run_scenario.foreign_participants(ros_domain, ['robot_0', 'robot_1'])
    assert reason is not None
    assert '/robot_1/stray' in reason and ('/robot_1/cmd_vel' in reason
                                           or '/diagnostics' in reason)


def test_stranger_publishing_on_a_run_topic_mid_run_fails_the_run(tmp_path, runners, strangers):
    runner = start_fake_run(tmp_path, runners)
    domain_id = runner_domain(runner)
    wait_until_running(runner)
    # Same name as the run's own planner: only the second publisher gives it away.
    strangers(domain_id, '-r', '__ns:=/robot_0', '-r', '__node:=planner')
    assert runner.wait(timeout=60) == 1
    recorded = json.loads((tmp_path / 'runner' / 'metrics.json').read_text())
    assert '/robot_0/cmd_vel' in recorded['failure'], recorded['failure']
    assert '/robot_0/planner' in recorded['failure']
    assert processes_with_token(runner.token) == []


def test_stranger_publishing_elsewhere_mid_run_fails_the_run(tmp_path, runners, strangers):
    runner = start_fake_run(tmp_path, runners)
    domain_id = runner_domain(runner)
    wait_until_running(runner)
    strangers(domain_id, '-r', '__ns:=/elsewhere', '-r', '__node:=chatter')
    assert runner.wait(timeout=60) == 1
    recorded = json.loads((tmp_path / 'runner' / 'metrics.json').read_text())
    assert '/elsewhere/chatter' in recorded['failure'], recorded['failure']


def test_recorder_names_a_stray_simulator_on_its_domain(children, ros2_executable, ros_domain,
                                                        probe):
    children.start('stray_sim', [ros2_executable('prvo_sim', 'sim'), '--ros-args',
                                 '-p', 'scenario:=headon2'])
    # The stray is up once it publishes its clock.
    probe.wait_for_message(Clock, '/clock', timeout=30.0)
    recorder = Recorder(ros_domain, ['robot_0', 'robot_1'])
    try:
        # Returns as soon as discovery shows the stray; the generous limit is for a loaded host.
        failure = recorder.foreign_traffic(30.0)
    finally:
        recorder.close()
    assert failure is not None
    assert f'ROS_DOMAIN_ID {ros_domain}' in failure and '/clock' in failure
    assert '/prvo_sim' in failure


def test_recorder_close_is_bounded_when_its_listener_stops_answering(ros_domain):
    # Fast DDS can deadlock in a participant's teardown holding the GIL: the process that
    # holds the participant may never run again. Stand-in: the listener stopped (SIGSTOP).
    recorder = Recorder(ros_domain, ['robot_0'])
    listener = recorder._process
    os.kill(listener.pid, signal.SIGSTOP)
    recorder.close()
    assert listener.returncode == -signal.SIGKILL


def test_recorder_close_lets_a_healthy_listener_leave_by_itself(ros_domain):
    recorder = Recorder(ros_domain, ['robot_0'])
    recorder.close()
    assert recorder._process.returncode == 0


def test_a_node_that_only_subscribes_is_welcome_before_the_run(tmp_path, runners,
                                                                released_domain, strangers):
    # `ros2 topic echo /clock` started before the runner, the user's usual order.
    strangers(released_domain, '-r', '__node:=watcher', mode='watcher')
    runner = start_fake_run(tmp_path, runners, '--domain-id', str(released_domain))
    assert runner_domain(runner) == released_domain
    wait_until_running(runner)
    runner.send_signal(signal.SIGINT)
    assert runner.wait(timeout=60) == 128 + signal.SIGINT, output(runner)
    assert 'in use' not in output(runner)
