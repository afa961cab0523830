"""The runner's command line: options, the domain claim, every seed's run and the exit code.

    run_scenario SCENARIO.yaml [--out DIR] [--method M] [--eta ETA] [--seed S] [--seeds N]
                 [--engine ros|inprocess] [--no-bag] [--no-animation]

Exit codes: 0 the run completed (collisions are a result, not an error), 1 a child failed, the
run timed out, processes it did not start interfered or a result could not be written, 2
refused (bad input, a domain or an output folder held by another runner, a domain used by
strangers: nothing was started and nothing written), 128 + signal number when interrupted
(also during the teardown; the results of a run that started are written all the same).
"""

import argparse
import contextlib
import os
import pathlib
import shlex
import signal
import sys

from prvo_sim.runner.domain import (
    DOMAIN_IDS,
    ClaimRefusedError,
    DomainRefusedError,
    claimed_domain,
    claimed_folder,
    requested_domain,
)
from prvo_sim.runner.outputs import Ending, OutputError, print_summary, write_summary
from prvo_sim.runner.processes import (
    INTERRUPT_SIGNALS,
    INTERRUPTS,
    RunInterruptedError,
    untranslated,
)
from prvo_sim.runner.session import (
    ENGINES,
    METHODS,
    RunSpec,
    check_planner_maps,
    run_eta,
    run_once,
)
from prvo_sim.step_timing import MODES

PROGRAM = 'run_scenario'
MAX_SEEDS = 1000  # runs of one sweep


class UsageError(Exception):
    """Bad input detected before anything started (exit code 2)."""


class _ArgumentParser(argparse.ArgumentParser):
    """An argument parser that reports errors as UsageError instead of exiting."""

    def error(self, message):
        raise UsageError(message)


def build_parser():
    """Return the command-line parser of the runner."""
    parser = _ArgumentParser(
        prog=PROGRAM,
        description='Run a PRVO scenario: simulator plus one planner per robot, recorded.')
    parser.add_argument('scenario', help='scenario YAML file (or the name of a shipped one)')
    parser.add_argument('--out', default=None,
                        help='output folder (default: results/<scenario name>)')
    parser.add_argument('--method', choices=METHODS, default='prvo',
                        help='planner variant (default: prvo)')
    parser.add_argument('--eta', type=float, default=None,
                        help='collision-avoidance probability in (0, 1) for every robot '
                        "(default: each robot's planner eta)")
    parser.add_argument('--seed', type=int, default=None,
                        help="random seed (default: the scenario's)")
    parser.add_argument('--seeds', type=int, default=1,
                        help='repeat over N consecutive seeds from --seed and aggregate')
    parser.add_argument('--mode', choices=MODES, default='lockstep',
                        help='simulator stepping (default: lockstep)')
    parser.add_argument('--engine', choices=ENGINES, default='ros',
                        help='ros: a simulator and a planner per robot, as processes on a ROS '
                        'domain; inprocess: the same world and planners in this process, no '
                        'DDS (lockstep only; the same trajectories) (default: ros)')
    parser.add_argument('--timeout', type=float, default=None,
                        help='wall-clock limit per run [s] (default: 10 x duration + 60)')
    parser.add_argument('--domain-id', type=int, default=None,
                        help='ROS_DOMAIN_ID, held exclusively (default: an exported '
                        f'ROS_DOMAIN_ID, else a free one in {DOMAIN_IDS.start}..'
                        f'{DOMAIN_IDS.stop - 1})')
    parser.add_argument('--sim-command', default=None,
                        help="command to start instead of prvo_sim's sim (ROS args appended)")
    parser.add_argument('--planner-command', default=None,
                        help="command to start instead of prvo_planner's planner")
    parser.add_argument('--no-bag', dest='bag', action='store_false',
                        help='record no rosbag2 bag (default: <out>/bag/, MCAP storage)')
    parser.add_argument('--no-animation', dest='animation', action='store_false',
                        help='draw no animation (default: <out>/trajectories.gif)')
    parser.add_argument('--quiet', action='store_true', help='no progress line')
    return parser


def parse_arguments(argv, environment=None):
    """Parse and check ARGV; return (options, scenario). Raise UsageError on bad input.

    options.domain_id becomes the domain asked for (--domain-id, else ROS_DOMAIN_ID from
    ENVIRONMENT, default os.environ; None for a free one) and options.domain_source says which.
    """
    from prvo_planner.maps import MapTooLargeError
    from prvo_sim.scenario import (
        MAX_SEED,
        ScenarioError,
        check_team_memory,
        find_scenario,
        load_scenario,
    )

    options = build_parser().parse_args(argv)
    if options.eta is not None and not 0.0 < options.eta < 1.0:
        raise UsageError(f'--eta: {options.eta} is outside (0, 1)')
    if not 1 <= options.seeds <= MAX_SEEDS:
        raise UsageError(f'--seeds: {options.seeds} is outside 1..{MAX_SEEDS}')
    if options.timeout is not None and not options.timeout > 0.0:
        raise UsageError(f'--timeout: {options.timeout} is not a positive time')
    if options.engine == 'inprocess':
        for name, value in (('--mode', options.mode if options.mode != 'lockstep' else None),
                            ('--domain-id', options.domain_id),
                            ('--sim-command', options.sim_command),
                            ('--planner-command', options.planner_command)):
            if value is not None:
                raise UsageError(f'{name}: not with --engine inprocess (it runs no ROS '
                                 'processes and steps in lockstep)')
    try:
        options.domain_id, options.domain_source = requested_domain(
            options.domain_id, os.environ if environment is None else environment)
    except ValueError as error:
        raise UsageError(str(error)) from None
    for name in ('sim_command', 'planner_command'):
        command = getattr(options, name)
        if command is not None and not shlex.split(command):
            raise UsageError(f"--{name.replace('_', '-')}: empty command")
    try:
        scenario = load_scenario(find_scenario(options.scenario), seed=options.seed)
        check_team_memory(scenario, engine=options.engine, bag=options.bag)
    except ScenarioError as error:
        raise UsageError(str(error)) from None
    except OSError as error:
        raise UsageError(f'{options.scenario}: {error.strerror or error}') from None
    try:
        check_planner_maps(scenario, options.method, options.eta)
    except MapTooLargeError as error:
        key = 'walls' if scenario.static_world.map_grid is None else 'map'
        raise UsageError(f'{scenario.path}: {key}: the planners cannot build the static world: '
                         f'{error}') from None
    last_seed = scenario.seed + options.seeds - 1
    if last_seed > MAX_SEED:
        raise UsageError(f'--seeds: {options.seeds} seeds from {scenario.seed} end at seed '
                         f'{last_seed}, outside 0..{MAX_SEED}')
    options.out = pathlib.Path(options.out or pathlib.Path('results') / scenario.name)
    check_writable(options.out)
    return options, scenario


def check_writable(folder):
    """Raise UsageError unless FOLDER exists as a writable folder or could be created.

    Nothing is created: a refused run leaves no trace.
    """
    folder = pathlib.Path(folder).absolute()
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        reason = 'Not a directory'
    elif not os.access(existing, os.W_OK | os.X_OK):
        reason = 'Permission denied'
    else:
        return
    raise UsageError(f'--out: cannot write to {folder}: {reason} ({existing})')


def run(options, scenario):
    """Claim the output folder and the domain (ROS engine), run every seed; return the exit code.

    An interrupted sweep still writes the summary of the seeds it ran.
    """
    from prvo_sim.runner.recorder import foreign_participants

    eta = run_eta(options, scenario)
    seeds = [scenario.seed + offset for offset in range(options.seeds)]
    robot_names = [robot.name for robot in scenario.robots]
    runs = []
    interrupted = None
    with contextlib.ExitStack() as claim:
        try:
            claim.enter_context(claimed_folder(options.out))
        except ClaimRefusedError as error:
            print(f'{PROGRAM}: error: {error}', file=sys.stderr)
            return 2
        if options.engine == 'inprocess':
            from prvo_sim.runner.inprocess import run_inprocess

            print(f'{PROGRAM}: in-process engine (no ROS processes, no domain)', flush=True)
            run_one = run_inprocess
        else:
            try:
                domain_id = claim.enter_context(claimed_domain(
                    options.domain_id,
                    vet=lambda domain_id: foreign_participants(domain_id, robot_names)))
            except DomainRefusedError as error:
                print(f'{PROGRAM}: error: {error}', file=sys.stderr)
                return 2
            print(f'{PROGRAM}: ROS_DOMAIN_ID {domain_id} ({options.domain_source})',
                  flush=True)

            def run_one(spec):
                return run_once(spec, domain_id)
        try:
            for seed in seeds:
                out_dir = options.out if options.seeds == 1 else options.out / f'seed_{seed}'
                result = run_one(RunSpec(options, scenario, eta, seed, out_dir))
                runs.append((result.metrics, out_dir))
                print_summary(result.metrics, out_dir)
                if result.interrupted is not None:
                    interrupted = result.interrupted
                    break
        except RunInterruptedError as interruption:
            # Between two seeds: the seeds that ran are summarised.
            print(f'{PROGRAM}: interrupted by {interruption}', file=sys.stderr)
            interrupted = interruption.signum
        except OutputError as error:
            print(f'{PROGRAM}: error: {error}', file=sys.stderr)
            return 1
        if options.seeds > 1 and runs:
            with INTERRUPTS.teardown():
                write_summary(options.out, runs)
    if interrupted is not None:
        return 128 + interrupted
    return 0 if all(Ending(run_metrics['ending']).completed for run_metrics, _ in runs) else 1


def run_interruptibly(program, job):
    """Return JOB()'s exit code, with the interrupt signals turned into RunInterruptedError.

    A signal that arrives when no child is alive ends PROGRAM with 128 + signal.
    """
    previous_handlers = {signum: signal.signal(signum, INTERRUPTS.handle)
                         for signum in INTERRUPT_SIGNALS}
    try:
        with untranslated():
            return job()
    except RunInterruptedError as interruption:
        print(f'{program}: interrupted by {interruption}', file=sys.stderr)
        return 128 + interruption.signum
    finally:
        for signum, handler in previous_handlers.items():
            signal.signal(signum, handler)


def main(argv=None):
    """Run the scenario runner's command line; return the exit code."""
    argv = sys.argv[1:] if argv is None else argv
    try:
        options, scenario = parse_arguments(argv)
    except UsageError as error:
        print(f'{PROGRAM}: error: {error}', file=sys.stderr)
        return 2
    return run_interruptibly(PROGRAM, lambda: run(options, scenario))
