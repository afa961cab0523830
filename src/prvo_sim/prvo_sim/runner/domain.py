"""Exclusive claims: a run owns its ROS_DOMAIN_ID and its output folder, or refuses them.

A claim is an flock on DOMAIN_LOCK_DIR/<id>.lock (a domain) or FOLDER_LOCK_DIR/<hash>.lock (an
output folder, by its resolved path), which holds the claimant's pid and command line so that
a refused runner can say who holds it. Test fixtures claim their domains the same way, so runs
and tests on one machine never share one.
"""

import contextlib
import fcntl
import hashlib
import os
import pathlib
import shlex
import sys
import tempfile

# Ids above 101 put Fast DDS's ports into Linux's ephemeral range; 0 is everyone's default.
DOMAIN_IDS = range(1, 102)
# What ROS 2 accepts at all (an explicit id is checked against it).
VALID_DOMAIN_IDS = range(0, 233)
DOMAIN_LOCK_DIR = pathlib.Path(tempfile.gettempdir()) / 'prvo-ros-domains'
FOLDER_LOCK_DIR = pathlib.Path(tempfile.gettempdir()) / 'prvo-run-folders'


class ClaimRefusedError(Exception):
    """What a run asked to hold is held by another claimant (or unfit); the text says why."""


class DomainRefusedError(ClaimRefusedError):
    """The domain asked for is held by another claimant or used by strangers."""


def _command_line():
    """Return this process's command line as typed (python -m ... rather than a path)."""
    try:
        arguments = pathlib.Path('/proc/self/cmdline').read_bytes().rstrip(b'\0').split(b'\0')
        return shlex.join(argument.decode(errors='replace') for argument in arguments)
    except OSError:
        return shlex.join([sys.executable, *sys.argv])


def _lock(domain_id):
    """Claim DOMAIN_ID; return the open lock file descriptor, or (None, holder description)."""
    return _lock_file(DOMAIN_LOCK_DIR, f'{domain_id}.lock')


def _lock_file(folder, name):
    """Claim FOLDER/NAME; return the open lock file descriptor, or (None, holder description)."""
    folder.mkdir(exist_ok=True)
    path = folder / name
    try:
        # Not truncated on open: the holder's pid and command line are in it.
        descriptor = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as error:
        return None, f'{path} cannot be opened ({error.strerror})'
    try:
        fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        holder = ''
        with contextlib.suppress(OSError):
            holder = os.pread(descriptor, 4096, 0).decode(errors='replace').strip()
        os.close(descriptor)
        pid, _, command = holder.partition(' ')
        return None, (f'pid {pid} ({command})' if pid.isdigit() else f'the holder of {path}')
    os.ftruncate(descriptor, 0)
    os.pwrite(descriptor, f'{os.getpid()} {_command_line()}\n'.encode(), 0)
    return descriptor, None


def _release(descriptor):
    os.ftruncate(descriptor, 0)
    fcntl.flock(descriptor, fcntl.LOCK_UN)
    os.close(descriptor)


@contextlib.contextmanager
def claimed_domain(requested, vet=None, candidates=DOMAIN_IDS):
    """Yield a ROS_DOMAIN_ID held exclusively until the block ends.

    REQUESTED (an id, or None for the first free one in the range CANDIDATES, by default
    DOMAIN_IDS) is claimed or refused with DomainRefusedError naming its holder. VET(domain_id),
    if given, returns None for a domain fit to use, else the reason it is not: a requested
    domain is then refused, an automatic choice moves on to the next id.
    """
    if requested is not None:
        descriptor, holder = _lock(requested)
        if descriptor is None:
            raise DomainRefusedError(f'ROS_DOMAIN_ID {requested} is held by {holder}')
        try:
            reason = vet(requested) if vet is not None else None
            if reason is not None:
                raise DomainRefusedError(reason)
            yield requested
        finally:
            _release(descriptor)
        return
    for domain_id in candidates:
        descriptor, _ = _lock(domain_id)
        if descriptor is None:
            continue
        try:
            if vet is not None and vet(domain_id) is not None:
                continue
            yield domain_id
            return
        finally:
            _release(descriptor)
    raise DomainRefusedError(
        f'no free ROS_DOMAIN_ID in {candidates.start}..{candidates.stop - 1}: every one is held '
        f'or used by other processes')


@contextlib.contextmanager
def claimed_folder(folder):
    """Hold output FOLDER exclusively until the block ends; ClaimRefusedError names a holder.

    Two runs writing one folder at once would replace each other's results.
    """
    resolved = pathlib.Path(folder).resolve()
    digest = hashlib.sha256(str(resolved).encode()).hexdigest()[:32]
    descriptor, holder = _lock_file(FOLDER_LOCK_DIR, f'{digest}.lock')
    if descriptor is None:
        raise ClaimRefusedError(f'--out: {resolved} is being written by {holder}')
    try:
        yield resolved
    finally:
        _release(descriptor)


def requested_domain(option, environment):
    """Return (domain id or None, where it came from): --domain-id, else ROS_DOMAIN_ID.

    Raise ValueError naming the source and the value when it is not an id in 0..232.
    """
    if option is not None:
        domain_id, source = option, '--domain-id'
    else:
        text = environment.get('ROS_DOMAIN_ID', '').strip()
        if not text:
            return None, f'chosen: the first free one in {DOMAIN_IDS.start}..{DOMAIN_IDS.stop - 1}'
        source = 'ROS_DOMAIN_ID in the environment'
        try:
            domain_id = int(text)
        except ValueError:
            raise ValueError(f'ROS_DOMAIN_ID: {text!r} is not an integer') from None
    if domain_id not in VALID_DOMAIN_IDS:
        name = '--domain-id' if source == '--domain-id' else 'ROS_DOMAIN_ID'
        raise ValueError(f'{name}: {domain_id} is outside {VALID_DOMAIN_IDS.start}..'
                         f'{VALID_DOMAIN_IDS.stop - 1}')
    return domain_id, f'from {source}'
