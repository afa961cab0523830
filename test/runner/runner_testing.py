"""Helpers of the runner tests: starting runners, finding their processes, waiting on events."""

import contextlib
import os
import pathlib
import re
import subprocess
import sys
import threading
import time
import uuid

import pytest
from worker_domains import worker_domain_ids

from prvo_sim.run_scenario import DomainRefusedError, claimed_domain

HERE = pathlib.Path(__file__).resolve().parent
FAKE_CHILD = f'{sys.executable} {HERE / "fake_child.py"}'
HEADON = str(HERE.parents[1] / 'src/prvo_sim/scenarios/headon2.yaml')
TOKEN_VARIABLE = 'PRVO_RUNNER_TEST_TOKEN'
# Two fake planners and a fake sim, each with a grandchild, the runner's watchdog and its
# recorder's listener.
FAKE_RUN_DESCENDANTS = 8
DOMAIN_LINE = re.compile(r'run_scenario: ROS_DOMAIN_ID (\d+) \(')


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


def start_runner(argv, tmp_path, label='runner', env=None, preexec_fn=None, drop=()):
    """Start `python -m prvo_sim.run_scenario ARGV` in a session of its own.

    Without ROS_DOMAIN_ID in ENV the runner chooses its own domain (tests hold claims of their
    own); the variables named in DROP are removed from its environment; PREEXEC_FN runs in the
    runner before it starts (a umask, a resource limit). The process gets .token (inherited by
    every descendant), .out_path and .err_path.
    """
    token = uuid.uuid4().hex
    child_env = dict(os.environ, PYTHONUNBUFFERED='1')
    child_env.pop('ROS_DOMAIN_ID', None)
    child_env.update(env or {})
    for name in drop:
        child_env.pop(name, None)
    child_env[TOKEN_VARIABLE] = token
    out_path, err_path = tmp_path / f'{label}.out', tmp_path / f'{label}.err'
    with open(out_path, 'w') as out_file, open(err_path, 'w') as err_file:
        process = subprocess.Popen(
            [sys.executable, '-m', 'prvo_sim.run_scenario', *argv], env=child_env,
            stdout=out_file, stderr=err_file, stdin=subprocess.DEVNULL, start_new_session=True,
            preexec_fn=preexec_fn)
    process.token, process.out_path, process.err_path = token, out_path, err_path
    return process


def runner_domain(process, timeout=60.0):
    """Return the ROS_DOMAIN_ID a runner reports on its first line of output."""
    def first_line():
        lines = process.out_path.read_text().splitlines()
        return lines[0] if lines else None

    line = wait_for(first_line, timeout, 'the runner reporting its domain')
    match = DOMAIN_LINE.match(line)
    assert match, f'first line is not the domain: {line!r}'
    return int(match.group(1))


def listener_pids(token):
    """Return the pids of the live recorder listeners among the processes holding TOKEN."""
    return [pid for pid in processes_with_token(token)
            if b'prvo_sim.runner.listener' in pathlib.Path(f'/proc/{pid}/cmdline').read_bytes()]


def output(process):
    """Return what PROCESS wrote on stdout and stderr so far."""
    return process.out_path.read_text() + process.err_path.read_text()


def free_domain():
    """Return a domain id no one holds now, for a runner the test starts with --domain-id.

    The claim is released at once, so another claimant could take it before the runner does.
    Searched from the top of the range down (fixtures and automatic choices search upwards),
    from an offset of this process's own, so that test processes running at once do not meet.
    """
    ids = list(reversed(worker_domain_ids()))
    offset = os.getpid() % (len(ids) // 2)
    for domain_id in ids[offset:] + ids[:offset]:
        with contextlib.suppress(DomainRefusedError), claimed_domain(domain_id):
            return domain_id
    pytest.fail('no free ROS_DOMAIN_ID')
