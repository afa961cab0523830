"""Crowd benchmark: does every robot arrive, how soon, and how close do robots come.

    python -m prvo_sim.bench.crowds [--circles 8 16 24 48] [--seeds 1] [--teams 4]
                                    [--sweep 50] [--method prvo] [--eta ETA]
                                    [--certificate cantelli|certified] [--risk pairwise|joint]
                                    [--stall-escalation] [--keep-right ANGLE]
                                    [--json PATH] [--out DIR]

Runs on the in-process engine, to completion or the scenario's duration:

* circles of N robots swapping antipodal points under noise 0.05 (`team.circle_document`
  with the radii of CIRCLE_RADII: 4 m up to 16 robots, 6 m for 24, 7.7 m for 48), each over
  `--seeds` consecutive noise seeds from the scenario's;
* seeded random heterogeneous teams of TEAM_SIZE robots (`random_team_document`): radii
  0.2-0.45 m, speeds 0.6-1.2 m/s, starts and goals in a square of half-side 1 + 0.45 N m, every
  two starts (and every two goals, and each robot's start and goal) at least 0.4 of the
  half-side apart;
* with `--sweep S`, the first S teams of the sweep (`sweep_team_document`): random teams as
  above, of 6-20 robots each (a seeded size);
* the noise-free 20-robot circle (radius 5 m) with `--method rvo`, the deterministic baseline
  whose only recourse in a crowd is the fallback;
* beside them, on the same circles without noise, ir-sim's sampled RVO
  (`irsim.lib.algorithm.rvo`) and RVO2's ORCA (`pyrvo`) when they are importable; neither is a
  dependency of prvo, and their rows say so when absent.

The circles and teams plan with the planner's default `eta`, `certificate` and `risk`;
`--eta`, `--certificate` and `--risk` set them, to see what the guarantee costs in time, and
`--stall-escalation` turns on the planner's escalation (`prvo_planner.escalation`) and
`--keep-right` sets the planner's lean to the right (`prvo_planner.lanes`; 0 turns it off). Per
run it prints one Markdown row: arrivals, makespan (the last robot's arrival) and its ratio to
the straight-line time (the longest start-to-goal distance over max speed), the mean time to
goal over the mean straight-line time, the paths' length (each up to its arrival) over the
straight lines', the minimum surface-to-surface separation, contacts, the fraction of planned
robot-steps without a feasible velocity, the stalls (`StallMonitor`, the planner's rule of
`prvo_planner.stalls`: a robot away from its goal that gains less than 0.5 m toward it in
10 s), each also printed with its time, position, command reversals and binding constraints,
the longest stall [s] and the longest time a robot stayed within 0.5 m of one spot away from
its goal [s] (`prvo_planner.stalls`' dwell).

Exit codes: 0 every robot of the circles and teams arrived, 1 one did not, 2 bad input, 130
when interrupted.
"""

import argparse
import collections
import math
import pathlib
import sys

import numpy as np

from prvo_planner import stalls
from prvo_planner.core.config import CERTIFICATES, RISKS
from prvo_planner.parameters import DEFAULTS
from prvo_sim.bench.engine import report, run_team
from prvo_sim.bench.team import (
    DT,
    GOAL_TOLERANCE,
    NOISE_STD,
    PEER_TIME_HORIZON,
    circle_document,
    write_scenario,
)

CIRCLE_RADII = {8: 4.0, 16: 4.0, 24: 6.0, 48: 7.7}
DEFAULT_CIRCLES = tuple(CIRCLE_RADII)
DEFAULT_TEAMS = 4
TEAM_SIZE = 14
TEAM_SEED = 2026
TEAM_RADII = (0.2, 0.45)  # m
TEAM_SPEEDS = (0.6, 1.2)  # m/s
TEAM_HALF_SIDE = (1.0, 0.45)  # m: 1 + 0.45 N
TEAM_SPACING = 0.4  # of the half-side
TEAM_DURATION = 90.0  # s
SWEEP_SEED = 4242
SWEEP_SIZES = (6, 20)  # robots, both included
# What the circles and teams plan with unless the command line says otherwise.
PLANNER_DEFAULTS = {name: DEFAULTS[name] for name in ('eta', 'certificate', 'risk')}
FALLBACK_CIRCLE = (20, 5.0)  # robots, radius [m]: noise-free, --method rvo
APPROACH_TIME = 0.5  # s: the peers slow down near the goal as the planner does (its default)
PEERS = ('irsim-rvo', 'orca')


def circle_radius_of(count):
    """Return the start circle's radius [m] of a COUNT robot crowd circle."""
    return CIRCLE_RADII.get(count, max(4.0, count / 4.0))


def crowd_circle_document(count, radius, noise_std=NOISE_STD):
    """Return the scenario document of COUNT robots on a RADIUS circle with NOISE_STD noise."""
    document = circle_document(count, radius=radius)
    document['name'] = f'crowd_circle{count}'
    document['noise'] = {'position_std': noise_std, 'velocity_std': noise_std,
                         'actuation_std': noise_std}
    return document


def _spaced_points(rng, count, half_side, spacing, avoid=None):
    """Draw COUNT points in the square, pairwise >= SPACING apart and from AVOID's rows."""
    points = []
    while len(points) < count:
        candidate = rng.uniform(-half_side, half_side, size=2)
        if any(np.hypot(*(candidate - point)) < spacing for point in points):
            continue
        if avoid is not None and np.hypot(*(candidate - avoid[len(points)])) < spacing:
            continue
        points.append(candidate)
    return np.array(points)


def random_team_document(index, count=TEAM_SIZE, seed=TEAM_SEED):
    """Return random heterogeneous team INDEX (seeded by SEED and INDEX) of COUNT robots."""
    rng = np.random.default_rng([seed, index])
    half_side = TEAM_HALF_SIDE[0] + TEAM_HALF_SIDE[1] * count
    spacing = TEAM_SPACING * half_side
    starts = _spaced_points(rng, count, half_side, spacing)
    goals = _spaced_points(rng, count, half_side, spacing, avoid=starts)
    radii = rng.uniform(*TEAM_RADII, size=count)
    speeds = rng.uniform(*TEAM_SPEEDS, size=count)
    robots = [{'name': f'robot_{robot}',
               'start': [round(float(value), 4) + 0.0 for value in starts[robot]],
               'goal': [round(float(value), 4) + 0.0 for value in goals[robot]],
               'radius': round(float(radii[robot]), 3),
               'max_speed': round(float(speeds[robot]), 3)} for robot in range(count)]
    return {
        'name': f'crowd_team{index}',
        'description': f'Random heterogeneous team {index} of {count} robots (crowd benchmark).',
        'seed': seed + index, 'dt': DT, 'duration': TEAM_DURATION,
        'goal_tolerance': GOAL_TOLERANCE,
        'noise': {'position_std': NOISE_STD, 'velocity_std': NOISE_STD,
                  'actuation_std': NOISE_STD},
        'robots': robots,
    }


def sweep_team_document(index, seed=SWEEP_SEED):
    """Return random team INDEX of the sweep: `random_team_document` of a seeded size."""
    count = int(np.random.default_rng([seed, index]).integers(SWEEP_SIZES[0],
                                                              SWEEP_SIZES[1] + 1))
    document = random_team_document(index, count, seed)
    document['name'] = f'sweep_team{index}'
    return document


class StallMonitor:
    """Finds the robots of a team that stall (`prvo_planner.stalls`: the planner's own rule).

    Called after every step (`run_team`'s observer), it watches every planned robot's true
    position with a `prvo_planner.stalls.StallMonitor`. Each stall is reported once, when first
    seen; a report holds the time, the robot's position and distance to its goal, the distance
    gained over the window, how often its command reversed (turned by more than 90 degrees from
    one step to the next) within the window, its mean command, and the binding constraints of
    its last plan (`binding_constraints`).
    """

    def __init__(self, scenario):
        self.names = [robot.name for robot in scenario.robots]
        self.goals = np.array([robot.goal for robot in scenario.robots])
        self.tolerance = scenario.goal_tolerance
        self.monitors = {index: stalls.StallMonitor()
                         for index, robot in enumerate(scenario.robots)
                         if robot.scripted is None}
        self.commands = collections.deque()  # (time, commands (N, 2)) of the last window
        self.stalled = {}  # robot -> its StallStatus while stalled
        self.stalls = []

    def __call__(self, team, step):
        """Take STEP of TEAM; record the stalls it shows."""
        self.commands.append((step.time, step.commands))
        while (len(self.commands) > 1
               and self.commands[1][0] <= step.time - stalls.STALL_WINDOW + 1e-9):
            self.commands.popleft()
        for robot, monitor in self.monitors.items():
            status = monitor.update(step.time, step.states[robot, :2], self.goals[robot],
                                    self.tolerance)
            self.stalled.pop(robot, None)
            if status.stalled:
                self.stalled[robot] = status
            if status.began:
                self.stalls.append(self.report(team, robot, status))

    def report(self, team, robot, status):
        """Return the record of ROBOT's stall, first seen with STATUS."""
        commands = np.array([commands[robot] for _, commands in self.commands])
        turns = np.einsum('ij,ij->i', commands[1:], commands[:-1])
        return {'robot': self.names[robot], 'time_s': round(float(status.time), 2),
                'position': [round(float(value), 3) for value in status.position],
                'distance_to_goal_m': round(float(status.distance_to_goal), 3),
                'gained_m': round(float(status.gained), 3),
                'command_reversals': int((turns < 0.0).sum()),
                'mean_command': [round(float(value), 3) for value in commands.mean(axis=0)],
                'binding': binding_constraints(team, robot)}


def binding_constraints(team, robot):
    """Return ROBOT's last plan's `stalls.binding_conditions`: the neighbours nearest failing.

    [] when the robot did not plan (it stood at its goal with nobody coming) or nobody was near.
    """
    command = team.last_commands[robot]
    if command is None or command.result is None:
        return []
    request = team.last_requests[[index for index, agent in enumerate(team.agents)
                                  if agent is not None].index(robot)]
    return stalls.binding_conditions(request.problem, request.neighbour_names, command.result)


def arrival_times(times, positions, goals, tolerance):
    """Per robot, the time from which it stays within TOLERANCE of its goal (inf: never)."""
    inside = np.linalg.norm(positions - goals[None], axis=2) <= tolerance
    arrivals = np.full(goals.shape[0], math.inf)
    for robot in range(goals.shape[0]):
        outside = np.flatnonzero(~inside[:, robot])
        first = 0 if outside.size == 0 else outside[-1] + 1
        if first < times.size:
            arrivals[robot] = times[first]
    return arrivals


def min_separation(positions, radii):
    """Smallest surface-to-surface distance over steps and pairs, positions (T, N, 2)."""
    offsets = positions[:, :, None, :] - positions[:, None, :, :]
    gaps = np.linalg.norm(offsets, axis=-1) - (radii[:, None] + radii[None, :])
    pairs = np.triu_indices(radii.size, 1)
    return float(gaps[:, pairs[0], pairs[1]].min())


def contact_count(positions, radii):
    """Count the times two robots came into contact (a pair entering overlap counts once)."""
    offsets = positions[:, :, None, :] - positions[:, None, :, :]
    touching = np.linalg.norm(offsets, axis=-1) < radii[:, None] + radii[None, :]
    pairs = np.triu_indices(radii.size, 1)
    touching = touching[:, pairs[0], pairs[1]]
    entered = touching[1:] & ~touching[:-1]
    return int(touching[0].sum() + entered.sum())


def path_ratio(times, positions, starts, goals, arrivals):
    """Return the robots' summed path lengths, each up to its arrival, over their straight lines.

    A robot that never arrives counts its whole path.
    """
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=2)
    ends = np.searchsorted(times, np.minimum(arrivals, times[-1]), side='right') - 1
    travelled = sum(float(steps[:end, robot].sum()) for robot, end in enumerate(ends))
    return travelled / float(np.linalg.norm(goals - starts, axis=1).sum())


def run_row(label, planner, times, positions, starts, goals, radii, max_speeds, tolerance):
    """Return the benchmark row of one run from its trajectory, positions (T, N, 2)."""
    straight = np.linalg.norm(goals - starts, axis=1) / max_speeds
    arrivals = arrival_times(times, positions, goals, tolerance)
    arrived = np.isfinite(arrivals)
    makespan = float(arrivals.max()) if arrived.all() else None
    return {
        'run': label, 'planner': planner, 'robots': int(radii.size),
        'arrived': int(arrived.sum()), 'all_arrived': bool(arrived.all()),
        'makespan_s': None if makespan is None else round(makespan, 1),
        'makespan_ratio': None if makespan is None else round(float(makespan / straight.max()), 2),
        'mean_time_ratio': (round(float(arrivals.mean() / straight.mean()), 2)
                            if arrived.all() else None),
        'path_ratio': round(path_ratio(times, positions, starts, goals, arrivals), 2),
        'min_separation_m': round(min_separation(positions, radii), 3),
    }


def prvo_run(label, scenario, method):
    """Run SCENARIO on the in-process engine with METHOD; return its row, with its stalls."""
    monitor = StallMonitor(scenario)
    _, steps = run_team(scenario, method, observer=monitor)
    robots = scenario.robots
    times = np.array([step.time for step in steps])
    states = np.array([step.states for step in steps])
    radii = np.array([robot.radius for robot in robots])
    row = run_row(label, method, times, states[:, :, :2],
                  np.array([robot.start for robot in robots]),
                  np.array([robot.goal for robot in robots]), radii,
                  np.array([robot.max_speed for robot in robots]), scenario.goal_tolerance)
    moving = np.array([step.commands.any(axis=1) | ~step.feasible for step in steps])
    feasible = np.array([step.feasible for step in steps])
    row['contacts'] = contact_count(states[:, :, :2], radii)
    row['infeasible_fraction'] = round(float((moving & ~feasible).sum() / max(moving.sum(), 1)),
                                       4)
    row.update(stalls.stall_summary(monitor.monitors.values()))
    row['stall_reports'] = monitor.stalls
    return row


def preferred_velocities(positions, goals, max_speed, tolerance):
    """Return the peers' preferred velocities, as the planner's agent computes them."""
    offsets = goals - positions
    distances = np.linalg.norm(offsets, axis=1)
    speeds = np.minimum(max_speed, distances / APPROACH_TIME)
    with np.errstate(invalid='ignore', divide='ignore'):
        preferred = offsets * (speeds / distances)[:, None]
    preferred[distances <= tolerance] = 0.0
    return preferred


def peer_step_function(peer, count, starts, radius, max_speed):
    """Return step(positions, velocities, preferred) -> velocities of PEER, None if absent."""
    if peer == 'irsim-rvo':
        try:
            from irsim.lib.algorithm.rvo import reciprocal_vel_obs
        except ImportError:
            return None

        def step(positions, velocities, preferred):
            chosen = np.empty_like(velocities)
            for index in range(count):
                state = [*positions[index], *velocities[index], radius, *preferred[index]]
                others = [[*positions[other], *velocities[other], radius]
                          for other in range(count) if other != index]
                chosen[index] = reciprocal_vel_obs(
                    state, others, vxmax=max_speed, vymax=max_speed, acce=1.0,
                    factor=1.0).cal_vel('rvo')
            speeds = np.linalg.norm(chosen, axis=1, keepdims=True)
            return np.where(speeds > max_speed, chosen * max_speed / np.maximum(speeds, 1e-12),
                            chosen)
        return step
    try:
        import pyrvo
    except ImportError:
        return None
    simulator = pyrvo.RVOSimulator(DT, 10.0, count, PEER_TIME_HORIZON, PEER_TIME_HORIZON,
                                   radius, max_speed)
    for start in starts:
        simulator.add_agent(tuple(start))

    def step(positions, velocities, preferred):
        for index in range(count):
            simulator.set_agent_position(index, tuple(positions[index]))
            simulator.set_agent_velocity(index, tuple(velocities[index]))
            simulator.set_agent_pref_velocity(index, tuple(preferred[index]))
        simulator.do_step()
        return np.array([simulator.get_agent_velocity(index).to_tuple()
                         for index in range(count)])
    return step


def peer_run(peer, count, radius):
    """Run PEER on the noise-free COUNT robot circle of RADIUS; return its row (None if absent)."""
    document = crowd_circle_document(count, radius, noise_std=0.0)
    starts = np.array([robot['start'] for robot in document['robots']], dtype=float)
    goals = np.array([robot['goal'] for robot in document['robots']], dtype=float)
    robot_radius = document['robots'][0]['radius']
    max_speed = document['robots'][0]['max_speed']
    step = peer_step_function(peer, count, starts, robot_radius, max_speed)
    if step is None:
        return None
    positions, velocities = starts.copy(), np.zeros_like(starts)
    times, trajectory = [], []
    for index in range(int(round(document['duration'] / DT))):
        times.append(index * DT)
        trajectory.append(positions.copy())
        if np.all(np.linalg.norm(goals - positions, axis=1) <= GOAL_TOLERANCE):
            break
        velocities = step(positions, velocities,
                          preferred_velocities(positions, goals, max_speed, GOAL_TOLERANCE))
        positions = positions + DT * velocities
    trajectory = np.array(trajectory)
    radii = np.full(count, robot_radius)
    row = run_row(f'circle{count} r={radius:g} noise-free', peer, np.array(times), trajectory,
                  starts, goals, radii, np.full(count, max_speed), GOAL_TOLERANCE)
    row['contacts'] = contact_count(trajectory, radii)
    row.update(stalls.trajectory_stalls(np.array(times), trajectory, goals, GOAL_TOLERANCE))
    return row


COLUMNS = (('run', 'run'), ('planner', 'planner'), ('arrived', 'arrived'),
           ('makespan_s', 'makespan s'), ('makespan_ratio', 'makespan / straight'),
           ('mean_time_ratio', 'mean time / straight'), ('path_ratio', 'path / straight'),
           ('min_separation_m', 'min separation m'), ('contacts', 'contacts'),
           ('infeasible_fraction', 'infeasible steps'), *stalls.SUMMARY_COLUMNS)


def build_parser():
    """Return the command-line parser of the crowd benchmark."""
    parser = argparse.ArgumentParser(
        prog='python -m prvo_sim.bench.crowds',
        description='Crowd benchmark: circles and random heterogeneous teams, in process.')
    parser.add_argument('--circles', type=int, nargs='*', default=list(DEFAULT_CIRCLES),
                        help='circle team sizes (default: 8 16 24 48)')
    parser.add_argument('--seeds', type=int, default=1,
                        help="noise seeds per circle, consecutive from the scenario's "
                             '(default: 1)')
    parser.add_argument('--teams', type=int, default=DEFAULT_TEAMS,
                        help=f'random teams of {TEAM_SIZE} robots (default: {DEFAULT_TEAMS})')
    parser.add_argument('--sweep', type=int, default=0,
                        help=f'also the first SWEEP random teams of {SWEEP_SIZES[0]}-'
                             f'{SWEEP_SIZES[1]} robots of the sweep (default: 0)')
    parser.add_argument('--method', default='prvo', choices=('prvo', 'rvo', 'inflate'),
                        help='planner variant of the circles and teams (default: prvo)')
    parser.add_argument('--eta', type=float, default=None,
                        help="collision-avoidance probability of the circles and teams, in "
                             "(0, 1) (default: the planner's)")
    parser.add_argument('--certificate', default=None, choices=CERTIFICATES,
                        help="bound the circles' and teams' planners meet eta by (default: the "
                             "planner's)")
    parser.add_argument('--risk', default=None, choices=RISKS,
                        help="risk allocation of the circles and teams (default: the "
                             "planner's)")
    parser.add_argument('--stall-escalation', action='store_true',
                        help='the circles and teams escalate when stalled (the planner '
                             "parameter stall_escalation; default: the planner's, off)")
    parser.add_argument('--keep-right', type=float, default=None, metavar='ANGLE',
                        help='lean [rad] of the circles and teams toward their right when they '
                             "meet (the planner parameter keep_right; 0: off; default: the "
                             "planner's)")
    parser.add_argument('--no-fallback-circle', action='store_true',
                        help='skip the noise-free 20-robot circle with --method rvo')
    parser.add_argument('--no-peers', action='store_true',
                        help="skip ir-sim's RVO and ORCA on the noise-free circles")
    parser.add_argument('--json', type=pathlib.Path, default=None,
                        help='also write {"runs": [...], "notes": [...]} to this file')
    parser.add_argument('--out', type=pathlib.Path,
                        default=pathlib.Path('results/bench_crowds'),
                        help='folder of the scenarios (default: results/bench_crowds)')
    return parser


def planned_runs(options):
    """Return the (label, scenario document, method) of every in-process run, in order."""
    runs = []
    for count in options.circles:
        for offset in range(options.seeds):
            document = crowd_circle_document(count, circle_radius_of(count))
            document['seed'] += offset
            label = f'circle{count} r={circle_radius_of(count):g}'
            if options.seeds > 1:
                document['name'] += f'_seed{document["seed"]}'
                label += f' seed {document["seed"]}'
            runs.append((label, document, options.method))
    runs += [(f'team{index} N={TEAM_SIZE}', random_team_document(index), options.method)
             for index in range(options.teams)]
    for index in range(options.sweep):
        document = sweep_team_document(index)
        runs.append((f'sweep{index} N={len(document["robots"])}', document, options.method))
    chosen = {name: getattr(options, name) for name in ('eta', 'certificate', 'risk')
              if getattr(options, name) is not None}
    rules = {'stall_escalation': True} if options.stall_escalation else {}
    if options.keep_right is not None:
        rules['keep_right'] = options.keep_right
    for index, (label, document, method) in enumerate(runs):
        # The circles' documents hold circle8's eta: the planner's defaults replace it.
        document['planner'] = {**document.get('planner', {}), **PLANNER_DEFAULTS, **chosen,
                               **rules}
        runs[index] = (' '.join([label, *(f'{name} {value:g}' if name == 'eta'
                                          else str(value) for name, value in chosen.items()),
                                 *(name if value is True else f'{name} {value:g}'
                                   for name, value in rules.items())]), document, method)
    if not options.no_fallback_circle:
        count, radius = FALLBACK_CIRCLE
        runs.append((f'circle{count} r={radius:g} noise-free',
                     crowd_circle_document(count, radius, noise_std=0.0), 'rvo'))
    return runs


def stall_text(stall):
    """Return one line describing a StallMonitor record."""
    binding = ', '.join(f"{item['neighbour']} gap {item['gap_m']:.2f} m bound {item['bound']:.3f}"
                        f" ({item['kind']})" for item in stall['binding']) or 'none'
    return (f"{stall['robot']} at t = {stall['time_s']:.1f} s at "
            f"({stall['position'][0]:.2f}, {stall['position'][1]:.2f}), "
            f"{stall['distance_to_goal_m']:.2f} m from its goal, gained {stall['gained_m']:.2f} m "
            f"in {stalls.STALL_WINDOW:g} s, {stall['command_reversals']} command reversals, "
            f'binding: {binding}')


def main(argv=None):
    """Run the crowd benchmark's command line; return the exit code."""
    options = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    for count in options.circles:
        if count < 2:
            print(f'prvo_sim.bench.crowds: error: --circles: {count} is not a team (at least 2)',
                  file=sys.stderr)
            return 2
    if options.seeds < 1:
        print(f'prvo_sim.bench.crowds: error: --seeds: {options.seeds} '
              'is not a count (at least 1)', file=sys.stderr)
        return 2
    for name in ('teams', 'sweep'):
        if getattr(options, name) < 0:
            print(f'prvo_sim.bench.crowds: error: --{name}: {getattr(options, name)} is negative',
                  file=sys.stderr)
            return 2
    if options.eta is not None and not 0.0 < options.eta < 1.0:
        print(f'prvo_sim.bench.crowds: error: --eta: {options.eta} is not a probability in (0, 1)',
              file=sys.stderr)
        return 2
    rows, notes = [], []
    try:
        for label, document, method in planned_runs(options):
            scenario = write_scenario(document, options.out / f'{document["name"]}.yaml')
            rows.append(prvo_run(label, scenario, method))
            print(f'{label} ({method}): {rows[-1]["arrived"]}/{rows[-1]["robots"]} arrived, '
                  f'{rows[-1]["contacts"]} contacts, {rows[-1]["stalls"]} stalls', flush=True)
            for stall in rows[-1]['stall_reports']:
                print(f'  stall: {stall_text(stall)}', flush=True)
        for peer in () if options.no_peers else PEERS:
            for count in options.circles:
                row = peer_run(peer, count, circle_radius_of(count))
                if row is None:
                    notes.append(f'{peer}: not importable here, skipped')
                    break
                rows.append(row)
    except KeyboardInterrupt:
        print('prvo_sim.bench.crowds: interrupted', file=sys.stderr)
        return 130
    report(rows, COLUMNS, notes, options.json)
    # The deterministic baseline's circle is there for its separation, not its arrivals.
    checked = [row for row in rows if row['planner'] == options.method]
    return 0 if all(row['all_arrived'] for row in checked) else 1


if __name__ == '__main__':
    sys.exit(main())
