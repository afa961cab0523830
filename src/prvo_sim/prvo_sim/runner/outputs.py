"""The results of a run: metrics.json, trajectories.csv, .png and .gif, the bag, the summaries.

Results are written only by a run that started, metrics.json first, each file through a
temporary file in the same folder (so that the folder never holds a half-written file), after
removing an earlier run's (so that it never mixes two runs). metrics.json and trajectories.csv
are the results: if one cannot be written the run fails with OutputError. The plot, the bag
and the animation are views of them: one that cannot be written (a full disk) costs a warning
line and that file only, and an interrupt while the animation is drawn costs the animation.
Files get the mode the umask gives, as any file a program creates.
"""

import contextlib
import csv
from dataclasses import dataclass
import enum
import json
import math
import os
import pathlib
import signal
import sys
import tempfile

import numpy as np

from prvo_sim import metrics
from prvo_sim.runner.bag import BAG_FOLDER
from prvo_sim.runner.processes import INTERRUPTS, RunInterruptedError
from prvo_sim.turns import GOES, NONE, WAITS

RUN_RESULTS = ('trajectories.csv', 'trajectories.png', 'trajectories.gif', 'metrics.json')
AGGREGATED_KEYS = ('success_rate', 'collisions', 'min_separation', 'wall_contacts',
                   'min_wall_clearance', 'makespan',
                   'mean_time_to_goal', 'infeasible_fraction', 'min_achieved_eta',
                   'planner_ms.median', 'planner_ms.p95', 'planner_ms.max',
                   'planner_cpu.node_ms.median', 'planner_cpu.plan_ms.p95',
                   'planner_cpu.planning_share', 'deadline_misses',
                   'sim_time', 'wall_time')
# The right of way's states as trajectories.csv names them.
TURN_NAMES = {NONE: 'none', GOES: 'goes', WAITS: 'waits'}


def planner_cpu(pairs):
    """Return metrics.json's `planner_cpu` of the (plan, node) CPU times [ms] PAIRS.

    `node_ms`: the planner nodes' process CPU per plan (median, p95, max); `plan_ms`: the plans'
    own CPU (the planning thread's, so without the waits for a core that the wall-clock
    `planner_ms` includes); `planning_share`: the plans' share of the nodes' CPU, None without
    pairs (the in-process engine).
    """
    pairs = np.asarray(pairs, dtype=float).reshape(-1, 2)
    total = float(pairs[:, 1].sum())
    return {'node_ms': metrics.distribution_summary(pairs[:, 1]),
            'plan_ms': metrics.distribution_summary(pairs[:, 0]),
            'planning_share': float(pairs[:, 0].sum()) / total if total > 0.0 else None}


class OutputError(Exception):
    """A result (metrics.json, trajectories.csv) could not be written; one line says why."""


class Ending(enum.Enum):
    """How a run ended; metrics.json's `ending` is the value."""

    ARRIVED = 'arrived'  # every robot arrived and stayed for the settle time
    DURATION = 'duration'  # the scenario's duration ran out first
    FAILED = 'failed'  # see metrics.json's `failure`
    INTERRUPTED = 'interrupted'  # SIGINT, SIGTERM or SIGHUP

    @property
    def completed(self):
        """Whether the run went to its end (collisions and late robots are results)."""
        return self in (Ending.ARRIVED, Ending.DURATION)


@dataclass(frozen=True)
class Recording:
    """What a run recorded, by either engine.

    `times` (T,) [s]; `states` (T, N, 4) ground truth x, y, vx, vy; `commands` (T, N, 2) the
    world-frame command answering each state, NaN where none; `plan_times_ms` every plan's
    time [ms]; `deadline_misses` the simulator's count, None where unknown; `yaws` (T, N) the
    ground-truth headings [rad], None where unknown; `bag_messages` the run's messages for its
    bag (`runner.bag.BagMessages`), None when not recorded; `plan_tallies` {robot: (plans,
    infeasible plans, lowest achieved eta)} of the planned robots that planned, None where
    unknown; `turns` who held each passage and who waited at each step (`prvo_sim.turns.Turns`),
    None where unknown (a ROS run); `planner_cpu_ms` the (plan, node) CPU times [ms] the
    planner nodes reported (`reports.plan_status`), none on the in-process engine.
    """

    times: np.ndarray
    states: np.ndarray
    commands: np.ndarray
    plan_times_ms: tuple = ()
    deadline_misses: int = None
    yaws: np.ndarray = None
    bag_messages: object = None
    plan_tallies: dict = None
    turns: object = None
    planner_cpu_ms: tuple = ()

    @classmethod
    def empty(cls, robot_count):
        """Return a recording of no step."""
        return cls(np.zeros(0), np.zeros((0, robot_count, 4)), np.zeros((0, robot_count, 2)))


@dataclass(frozen=True)
class RunResult:
    """One run as the runner and the benchmarks read it.

    `metrics` is metrics.json's content; `interrupted` the signal number that stopped the run,
    else None.
    """

    ending: Ending
    metrics: dict
    interrupted: int = None

    @property
    def failure(self):
        """The one-line reason of a run that did not complete, else None."""
        return self.metrics.get('failure')


def write_outputs(spec, recording, ending, failure, wall_time):
    """Write a run's results (RUN_RESULTS and its bag); return its metrics.

    RECORDING may be None (nothing recorded); FAILURE is the one-line reason of an ENDING that
    is not completed. The bag (unless spec.bag is false) and the GIF (unless spec.animation is
    false) are left out when nothing was recorded.
    """
    scenario = spec.scenario
    names = [robot.name for robot in scenario.robots]
    recording = recording or Recording.empty(len(names))
    times, states, commands = recording.times, recording.states, recording.commands
    radii = np.array([robot.radius for robot in scenario.robots], dtype=float)
    goals = np.array([robot.goal for robot in scenario.robots], dtype=float)
    scripted = [robot.scripted is not None for robot in scenario.robots]
    run_metrics = {'scenario': scenario.name, 'method': spec.method, 'eta': spec.eta,
                   'seed': spec.seed, 'mode': spec.mode, 'engine': spec.engine,
                   'ending': ending.value}
    if times.size:
        measured = metrics.run_metrics(times, states[..., :2], radii, goals,
                                       scenario.goal_tolerance, names, scripted)
        contacts = metrics.contact_events(times, states[..., :2], radii)
    else:
        measured = {'robots': {name: {'arrived': None if is_scripted else False,
                                      'time_to_goal': None, 'path_length': None,
                                      'scripted': is_scripted}
                               for name, is_scripted in zip(names, scripted, strict=True)},
                    'scripted_robots': [name for name, is_scripted in zip(
                        names, scripted, strict=True) if is_scripted],
                    'success_rate': 0.0, 'collisions': 0, 'min_separation': None,
                    'makespan': None, 'mean_time_to_goal': None, 'sim_time': 0.0}
        contacts = []
    run_metrics.update({
        'robots': measured['robots'],
        'scripted_robots': measured['scripted_robots'],
        'success_rate': measured['success_rate'],
        'collisions': measured['collisions'],
        'min_separation': measured['min_separation'],
        'wall_contacts': 0,
        'min_wall_clearance': None,
        'makespan': measured['makespan'],
        'mean_time_to_goal': measured['mean_time_to_goal'],
        'planner_ms': metrics.distribution_summary(list(recording.plan_times_ms)),
        'planner_cpu': planner_cpu(recording.planner_cpu_ms),
        'deadline_misses': recording.deadline_misses,
        'sim_time': measured['sim_time'],
        'wall_time': round(wall_time, 3),
    })
    add_wall_metrics(run_metrics, states[..., :2], radii, scenario.static_world)
    add_plan_quality(run_metrics, recording.plan_tallies)
    if failure is not None:
        run_metrics['failure'] = failure
    run_metrics = finite_or_none(run_metrics)
    out_dir = spec.out_dir
    with INTERRUPTS.teardown():
        clear_results(out_dir, RUN_RESULTS)
        write_result(out_dir, 'metrics.json', lambda path: write_json(path, run_metrics))
        write_result(out_dir, 'trajectories.csv', lambda path: write_trajectories_csv(
            path, times, names, states, commands, recording.yaws, recording.turns))
        if times.size:
            from prvo_sim.plotting import plot_run

            write_view(out_dir, 'trajectories.png', lambda path: plot_run(
                path, times, states[..., :2],
                np.array([robot.start for robot in scenario.robots], dtype=float), goals, radii,
                names, contacts, plot_title(run_metrics), scripted, yaws=recording.yaws,
                static_world=scenario.static_world, turns=recording.turns))
        write_run_bag(spec, recording)
        if times.size and spec.animation:
            from prvo_sim.animation import animate_run

            # The animation draws headings from a fifth state column where they are known.
            drawn = (states if recording.yaws is None
                     else np.concatenate([states, recording.yaws[..., None]], axis=-1))
            with contextlib.suppress(RunInterruptedError), INTERRUPTS.abortable():
                write_view(out_dir, 'trajectories.gif', lambda path: animate_run(
                    path, times, drawn, goals, radii, names, plot_title(run_metrics),
                    position_std=[robot.noise.position_std for robot in scenario.robots],
                    scripted=scripted, static_world=scenario.static_world,
                    turns=recording.turns))
            if INTERRUPTS.last_signal is not None:
                warn(f'trajectories.gif not written: interrupted by '
                     f'{signal.Signals(INTERRUPTS.last_signal).name}')
    return run_metrics


def add_wall_metrics(run_metrics, positions, radii, static_world):
    """Add to RUN_METRICS each robot's and the run's wall contacts and least wall clearance.

    From the recorded ground truth POSITIONS (T, N, 2) against STATIC_WORLD (the scenario's
    walls, obstacles and map; `metrics.wall_metrics`).
    """
    walls = metrics.wall_metrics(positions, radii, list(run_metrics['robots']),
                                 None if static_world.empty else static_world.clearance)
    for name, robot in run_metrics['robots'].items():
        robot.update(walls['robots'][name])
    run_metrics['wall_contacts'] = walls['wall_contacts']
    run_metrics['min_wall_clearance'] = walls['min_wall_clearance']


def add_plan_quality(run_metrics, tallies):
    """Add to RUN_METRICS how far the plans met the chance constraint (metrics.plan_quality).

    Per planned robot and overall: `plans`, `infeasible_fraction` (plans without a velocity
    that meets every constraint: the returned one then carries a lower eta) and
    `min_achieved_eta`; None where unknown. A run never claims a guarantee it did not have.
    """
    quality = metrics.plan_quality(tallies or {})
    for name, robot in run_metrics['robots'].items():
        if robot.get('scripted'):
            continue
        robot.update(quality['robots'].get(
            name, {'plans': None, 'infeasible_fraction': None, 'min_achieved_eta': None}))
    run_metrics['infeasible_fraction'] = quality['infeasible_fraction']
    run_metrics['min_achieved_eta'] = quality['min_achieved_eta']


def warn(text):
    """Print a one-line warning of the runner."""
    print(f'run_scenario: warning: {text}', file=sys.stderr, flush=True)


def write_run_bag(spec, recording):
    """Write the bag of RECORDING into spec.out_dir, if it is kept and has messages.

    A bag that cannot be written costs the run its bag only: the other results are written.
    """
    from rosbags.rosbag2 import WriterError

    from prvo_sim.runner.bag import write_bag

    messages = recording.bag_messages
    if not spec.bag or messages is None or not any(messages.counts().values()):
        return
    for name, count, first in messages.missing_odometry(
            [robot.name for robot in spec.scenario.robots],
            [round(time * 1e9) for time in recording.times]):
        warn(f'{BAG_FOLDER}/ lacks {count} odometry message(s) of {name}, the first at '
             f't = {first * 1e-9:g} s: dropped by the middleware before the recorder took them')
    try:
        write_bag(spec.out_dir, recording.bag_messages, file_mode())
    except (OSError, WriterError) as error:
        warn(f'{BAG_FOLDER}/ not written: {error}')


def finite_or_none(value):
    """Return VALUE (nested dicts and lists) with every non-finite number replaced by None."""
    if isinstance(value, dict):
        return {key: finite_or_none(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(item) for item in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    return value


def write_json(path, document):
    """Write DOCUMENT to PATH as strict JSON (non-finite numbers as null)."""
    with open(path, 'w') as json_file:
        json.dump(finite_or_none(document), json_file, indent=2, allow_nan=False)
        json_file.write('\n')


def file_mode():
    """Return the mode of a new file under this process's umask (0o666 less the umask)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


def clear_results(folder, names):
    """Remove an earlier run's results NAMES and bag from FOLDER."""
    from prvo_sim.runner.bag import remove_bag

    for name in names:
        (pathlib.Path(folder) / name).unlink(missing_ok=True)
    remove_bag(folder)


def write_result(folder, name, write):
    """Write FOLDER/NAME with WRITE(path) through a temporary file; OutputError if it fails."""
    try:
        replace_result(folder, name, write)
    except OSError as error:
        raise OutputError(f'could not write {pathlib.Path(folder) / name}: '
                          f'{error.strerror or error}') from None


def write_view(folder, name, write):
    """Write FOLDER/NAME as write_result does; a failure is a warning line, not an error."""
    try:
        replace_result(folder, name, write)
    except OSError as error:
        warn(f'{name} not written: {error.strerror or error}')


def replace_result(folder, name, write):
    """Write FOLDER/NAME with WRITE(path) into a temporary file, then put it in place.

    The folder never holds a half-written file; the file gets the umask's mode.
    """
    descriptor, temporary = tempfile.mkstemp(dir=folder, prefix='.', suffix=f'-{name}')
    os.close(descriptor)
    try:
        write(pathlib.Path(temporary))
        os.chmod(temporary, file_mode())
        os.replace(temporary, pathlib.Path(folder) / name)
    finally:
        pathlib.Path(temporary).unlink(missing_ok=True)


def write_trajectories_csv(path, times, names, states, commands, yaws=None, turns=None):
    """Write one row per time and robot: ground truth, the command answering it, the heading.

    The columns are x, y, vx, vy, cmd_vx, cmd_vy, the ground-truth `yaw` (empty where YAWS
    is None), the robot's `right_of_way` ('none', 'goes' or 'waits') and its `passage` (an
    index of TURNS' shapes, empty with 'none'), both empty where TURNS (`prvo_sim.turns.Turns`)
    is None. Numbers are written exactly (the shortest text that reads back as the same
    double), so that runs can be compared to the last bit.
    """
    with open(path, 'w', newline='') as csv_file:
        writer = csv.writer(csv_file)
        writer.writerow(['time', 'robot', 'x', 'y', 'vx', 'vy', 'cmd_vx', 'cmd_vy', 'yaw',
                         'right_of_way', 'passage'])
        for step, time_s in enumerate(times):
            for robot, name in enumerate(names):
                command = ['' if math.isnan(value) else repr(float(value))
                           for value in commands[step, robot]]
                yaw = '' if yaws is None else repr(float(yaws[step, robot]))
                turn = ['', ''] if turns is None else turn_columns(turns, step, robot)
                writer.writerow([f'{time_s:.6g}', name,
                                 *(repr(float(value)) for value in states[step, robot]),
                                 *command, yaw, *turn])


def turn_columns(turns, step, robot):
    """Return [right_of_way, passage] of ROBOT at STEP of TURNS, as trajectories.csv has them."""
    state = int(turns.states[step, robot])
    return [TURN_NAMES[state], '' if state == NONE else str(int(turns.passages[step, robot]))]


def outcome(run_metrics):
    """Return a short description of how a run ended."""
    if 'failure' in run_metrics:
        return f"{run_metrics['ending'].upper()}: {run_metrics['failure']}"
    planned = [robot for robot in run_metrics['robots'].values() if not robot.get('scripted')]
    arrived = sum(robot['arrived'] for robot in planned)
    collisions = run_metrics['collisions']
    contact_text = 'no contact' if collisions == 0 else f'{collisions} contact(s)'
    wall_contacts = run_metrics.get('wall_contacts')
    if wall_contacts:
        contact_text += f', {wall_contacts} wall contact(s)'
    walkers = len(run_metrics['robots']) - len(planned)
    scripted_text = f' ({walkers} scripted)' if walkers else ''
    return (f'{arrived}/{len(planned)} arrived{scripted_text}, {contact_text}'
            f'{guarantee(run_metrics)}')


def guarantee(run_metrics):
    """Return ', <p>% of plans infeasible (achieved eta down to <e>)', or '' if none was."""
    fraction = run_metrics.get('infeasible_fraction')
    if not fraction:
        return ''
    return (f', {100.0 * fraction:.0f}% of plans infeasible (achieved eta down to '
            f"{run_metrics['min_achieved_eta']:.2f})")


def plot_title(run_metrics):
    """Return the figure title: scenario, method, eta, seed and outcome."""
    return (f"{run_metrics['scenario']}: method {run_metrics['method']}, eta "
            f"{format_eta(run_metrics['eta'])}, seed {run_metrics['seed']}\n"
            f'{outcome(run_metrics)}')


def format_eta(eta):
    """Return the run's eta for people: one number, or one per robot."""
    if eta is None:
        return 'n/a'
    if isinstance(eta, list):
        return '/'.join(f'{value:g}' for value in eta)
    return f'{eta:g}'


def _format(value, unit='', digits=2):
    return 'n/a' if value is None else f'{value:.{digits}f}{unit}'


def print_summary(run_metrics, out_dir):
    """Print one run's results on one screen."""
    print(f"{run_metrics['scenario']} | method {run_metrics['method']}, eta "
          f"{format_eta(run_metrics['eta'])} | seed {run_metrics['seed']} | {run_metrics['mode']}")
    print(f"  {'robot':<12} {'arrived':<8} {'time to goal':>12} {'path length':>12}")
    for name, robot in run_metrics['robots'].items():
        arrived = {True: 'yes', False: 'no', None: 'scripted'}[robot['arrived']]
        print(f"  {name:<12} {arrived:<8} "
              f"{_format(robot['time_to_goal'], ' s', 1):>12} "
              f"{_format(robot['path_length'], ' m'):>12}")
    planner_ms = run_metrics['planner_ms']
    print(f"  outcome: {outcome(run_metrics)}; success rate "
          f"{_format(run_metrics['success_rate'])}, "
          f"min separation {_format(run_metrics['min_separation'], ' m')}, "
          + ('' if run_metrics['min_wall_clearance'] is None else
             f"min wall clearance {_format(run_metrics['min_wall_clearance'], ' m')}, ")
          + f"makespan {_format(run_metrics['makespan'], ' s', 1)}")
    print(f"  planner ms median/p95/max {_format(planner_ms['median'])}/"
          f"{_format(planner_ms['p95'])}/{_format(planner_ms['max'])}; deadline misses "
          f"{run_metrics['deadline_misses']}; sim {_format(run_metrics['sim_time'], '', 1)} s "
          f"in {_format(run_metrics['wall_time'], '', 1)} s wall")
    cpu = run_metrics['planner_cpu']
    if cpu['planning_share'] is not None:
        node_ms, plan_ms = cpu['node_ms'], cpu['plan_ms']
        print(f"  planner node CPU ms per plan median/p95/max {_format(node_ms['median'])}/"
              f"{_format(node_ms['p95'])}/{_format(node_ms['max'])}, "
              f"{100.0 * cpu['planning_share']:.0f}% of it planning (the plan's own CPU "
              f"median/p95/max {_format(plan_ms['median'])}/{_format(plan_ms['p95'])}/"
              f"{_format(plan_ms['max'])})")
    written = [name for name in RUN_RESULTS if (out_dir / name).exists()]
    if (out_dir / BAG_FOLDER).is_dir():
        written.append(f'{BAG_FOLDER}/')
    written = ', '.join(written)
    logs = f' (child logs in {out_dir}/logs)' if run_metrics['engine'] == 'ros' else ''
    print(f'  results: {out_dir}/ {written}{logs}')


def write_summary(out_dir, runs):
    """Write and print the aggregate summary.json of a multi-seed run; return its dict."""
    first = runs[0][0]
    summary = {
        'scenario': first['scenario'], 'method': first['method'], 'eta': first['eta'],
        'mode': first['mode'], 'seeds': [run_metrics['seed'] for run_metrics, _ in runs],
        'runs': [{'seed': run_metrics['seed'], 'dir': str(run_dir),
                  'outcome': outcome(run_metrics)} for run_metrics, run_dir in runs],
        'failed_runs': sum(not Ending(run_metrics['ending']).completed
                           for run_metrics, _ in runs),
        'metrics': metrics.aggregate([run_metrics for run_metrics, _ in runs], AGGREGATED_KEYS),
    }
    write_result(out_dir, 'summary.json', lambda path: write_json(path, summary))
    print(f"{summary['scenario']} | method {summary['method']}, eta "
          f"{format_eta(summary['eta'])} | {len(runs)} seeds, {summary['failed_runs']} failed")
    print(f"  {'metric':<20} {'mean':>9} {'std':>9} {'min':>9} {'max':>9} {'n':>4}")
    for key, stats in summary['metrics'].items():
        print(f"  {key:<20} {_format(stats['mean'], '', 3):>9} {_format(stats['std'], '', 3):>9}"
              f" {_format(stats['min'], '', 3):>9} {_format(stats['max'], '', 3):>9}"
              f" {stats['n']:>4}")
    print(f'  results: {out_dir}/summary.json and seed_<n>/ folders')
    return summary
