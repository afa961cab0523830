"""Helpers of the runner tests: finding the processes a runner started, waiting on events."""

import pathlib
import sys
import threading
import time

import pytest

HERE = pathlib.Path(__file__).resolve().parent
FAKE_CHILD = f'{sys.executable} {HERE / "fake_child.py"}'
HEADON = str(HERE.parents[1] / 'src/prvo_sim/scenarios/headon2.yaml')
TOKEN_VARIABLE = 'PRVO_RUNNER_TEST_TOKEN'


def processes_with_token(token, exclude=()):
    """Return the pids of live processes whose environment holds TOKEN."""
    needle = f'{TOKEN_VARIABLE}={token}'.encode()
    pids = []
    for entry in pathlib.Path('/proc').iterdir():
        if not entry.name.isdigit() or int(entry.name) in exclude:
            continue
        try:
            environment = (entry / 'environ').read_bytes()
            state = (entry / 'stat').read_text().rsplit(')', 1)[1].split()[0]
        except OSError:
            continue
        if state != 'Z' and needle in environment.split(b'\0'):
            pids.append(int(entry.name))
    return pids


def live_group_members(pgid):
    """Return the pids of live (not zombie) processes in process group PGID."""
    members = []
    for entry in pathlib.Path('/proc').iterdir():
        try:
            fields = (entry / 'stat').read_text().rsplit(')', 1)[1].split()
        except (OSError, IndexError):
            continue
        if fields[0] != 'Z' and int(fields[2]) == pgid:
            members.append(int(entry.name))
    return members


def wait_for(condition, timeout, what):
    """Return CONDITION()'s first true value; fail after TIMEOUT s."""
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f'{what} did not happen within {timeout} s')
        threading.Event().wait(0.05)
