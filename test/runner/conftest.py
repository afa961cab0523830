"""Fixtures of the runner tests."""

import contextlib
import os
import signal
import subprocess

import pytest
from runner_testing import FAKE_CHILD, free_domain, processes_with_token, wait_for


def kill_tree(process):
    """SIGKILL PROCESS's group and every live process holding its test token (and their groups)."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    for pid in processes_with_token(process.token):
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(pid, signal.SIGKILL)
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)


@pytest.fixture
def runners():
    """Runners of a test (from runner_testing.start_runner); each tree is killed at teardown."""
    started = []
    yield started
    for process in started:
        kill_tree(process)


@pytest.fixture(scope='module')
def module_runners():
    """Runners the tests of one module share; each tree is killed after the module's last test."""
    started = []
    yield started
    for process in started:
        kill_tree(process)


@pytest.fixture
def released_domain():
    """Return a domain id free for a runner the test starts (see free_domain)."""
    return free_domain()


@pytest.fixture
def strangers(tmp_path):
    """Start fake planners (runner_testing.FAKE_CHILD planner) on a domain; killed at teardown.

    Call start(domain_id, *ros_arguments); returns the process once it publishes. With
    mode='watcher' the stranger only subscribes to /clock (returned once it has).
    """
    started = []

    def start(domain_id, *ros_arguments, mode='planner'):
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain_id), PYTHONUNBUFFERED='1',
                   ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
        log_path = tmp_path / f'stranger_{len(started)}.log'
        with open(log_path, 'w') as log_file:
            process = subprocess.Popen(
                [*FAKE_CHILD.split(), mode, '--ros-args', *ros_arguments], env=env,
                stdout=log_file, stderr=subprocess.STDOUT, start_new_session=True)
        process.token = None
        started.append(process)
        ready = 'subscribed' if mode == 'watcher' else 'publishing'
        wait_for(lambda: ready in log_path.read_text(), 60, f'the stranger {ready}')
        return process

    yield start
    for process in started:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
