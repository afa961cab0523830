"""Engine benchmark: teams of 8 to 200 robots on the in-process engine, and peers beside them.

    python -m prvo_sim.bench.engine [--robots 8 16 48 100 200] [--peer-robots 10 20 50]
                                    [--peers irsim-rvo rvo2-orca ...] [--planner NAME=VALUE ...]
                                    [--json PATH] [--out DIR] [--profile]

Every circle is the team benchmark's (`team.circle_document`: N robots of radius 0.3 m and max
speed 1 m/s swapping antipodal points, PRVO at eta 0.8 with Cantelli's bound, dt 0.1 s), on a
start circle of `circle_radius_of(N)`: circle8's 4 m, or N / 8 m once that is larger (100
robots on 12.5 m, 200 on 25 m). From 32 robots on, neighbours start 2 pi / 8 = 0.785 m apart
along the circle, 0.185 m between the robots' edges; the simulated duration is 7.5 s per
metre of diameter.

**Teams** (`--robots`). Each N robots under noise 0.05 (position, velocity and actuation) run
to completion on the in-process engine, one Markdown row each: the start circle's radius, wall
time (the steps alone: building the team is `setup s`), simulated time, their ratio (the
real-time factor, above 1 faster than real time), steps, robot-steps per wall second, the
agents' planning and the whole step per robot-step [ms of wall time, below], arrivals,
collisions and the process's peak RSS after the run (VmHWM: it only grows, so sizes run in
increasing order). Every 10 s of simulated time a progress line says how far a team is, so a
run cut short (`timeout -s INT`: the tables of what completed are still printed) still says
where it was. Trajectories go to DIR.

**Peers** (`--peer-robots`), on the same circles without noise, one row per N, each planner
run to its own end in the same process, one after the other: ms of wall time per robot-step,
the mean and the median, for

* `irsim-rvo`, ir-sim's numpy RVO (`irsim.lib.algorithm.rvo`; `time_peer`): the planning call
  alone, per robot: building `reciprocal_vel_obs` over every other robot and `cal_vel('rvo')`,
  as ir-sim's own behaviour does each step (the lists it is given, and the motion, untimed);
* `rvo2-orca`, RVO2's ORCA (`pyrvo`), and `navground-orca`, `navground-hrvo`, `navground-hl`,
  navground's ORCA, HRVO and HL (`navground`), through the wall benchmark's steppers
  (`walls.peer_trajectory`): the whole step of the peer's own simulator over the team, divided
  by the team's size. For RVO2 that is reading the positions, the preferred velocities, and
  `doStep` (its k-d tree, ORCA per robot, the motion); for navground `World.update` (each
  robot's sensing of its neighbours within 10 m, its behaviour, its kinematics, the motion).
  These include more than the planning call, so they bound it from above;
* PRVO, two columns: `PRVO plan`, the agents' planning per robot-step (each `StepRecord`'s
  `plan_ms`: the agents' plan requests, the core's team plan `plan_velocities`, the
  completions into commands, the announcements and routes, the team's share per robot), the
  counterpart of ir-sim's planning call; and `PRVO step`, the whole engine step
  (`InProcessTeam.do_step`: the odometry serialized and decoded, the tracks' Kalman updates,
  the planning, the world's motion) per robot-step, the counterpart of a peer's whole step;
* the ratios of PRVO's plan and step to ir-sim's RVO (of the means / of the medians), and
  below the table each planner's arrivals (robots within 0.2 m of their goal at the end).

A planner whose package is not importable here is skipped, with one printed note, and its
cells say n/a. None of the peers is a dependency of prvo: install them beside it, e.g. in a
scratch venv whose site-packages come after prvo's on PYTHONPATH.

`--planner NAME=VALUE` sets a planner parameter of every PRVO robot of both tables over the
circle's (values read as YAML; `--planner eta=0.95 certificate=certified` runs the planner
node's defaults).

With `--profile` each team runs under cProfile (CPU time) and a second table says where a
robot-step goes: the core's team plan (`plan_velocities`) and, within the plans, the compiled
kernels' own time (native code the profiler only enters and leaves), and around it the agents' plan
requests (beliefs, preferences, rules), their completions (commands), their own odometry and
the neighbours' tracks (Kalman updates), the odometry messages (serialized and decoded as a
subscriber gets them), the world's step and the announcements and routes; the rest is the
step's own bookkeeping. Profiled times are 1.3-2x the plain ones (the kernels' excepted):
compare within the table.

Exit codes: 0 every team arrived, 1 a team did not, 2 bad input, 130 when interrupted.
"""

import argparse
import cProfile
import json
import math
import pathlib
import pstats
import sys
import time

import numpy as np

from prvo_planner.bench import compiled_kernel
from prvo_sim.bench.team import (
    CIRCLE8_RADIUS,
    GOAL_TOLERANCE,
    circle_document,
    peak_rss_kib,
    write_scenario,
)
from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.outputs import write_trajectories_csv
from prvo_sim.runner.session import ArrivalRule, planner_values

DEFAULT_TEAM_SIZES = (8, 16, 48, 100)
DEFAULT_PEER_SIZES = (10, 20, 50)
KIB_PER_MIB = 1024.0
PEER_SPEED = 1.0  # m/s, the circle's max speed
PEER_APPROACH_DISTANCE = 1.0  # m: the peer's preferred speed slows linearly over the last metre
# Robots per metre of the start circle's radius, once the circle is larger than circle8's:
# issue 40's 100 robots on 12.5 m.
ROBOTS_PER_METRE = 8.0
PROGRESS_EVERY = 10.0  # s of simulated time between a team's progress lines
# The peers of the peer table, in its order, and the package each needs.
PEERS = ('irsim-rvo', 'rvo2-orca', 'navground-orca', 'navground-hrvo', 'navground-hl')
PEER_PACKAGES = {'irsim-rvo': 'irsim', 'rvo2-orca': 'pyrvo', 'navground-orca': 'navground',
                 'navground-hrvo': 'navground', 'navground-hl': 'navground'}
PEER_HEADERS = {'irsim-rvo': 'ir-sim RVO', 'rvo2-orca': 'RVO2 ORCA',
                'navground-orca': 'navground ORCA', 'navground-hrvo': 'navground HRVO',
                'navground-hl': 'navground HL'}


def circle_radius_of(count):
    """Return the start circle's radius [m] of COUNT robots: 4 m, or COUNT / 8 m if larger."""
    return max(CIRCLE8_RADIUS, count / ROBOTS_PER_METRE)


def engine_circle_document(count, noise=True):
    """Return the benchmark's circle of COUNT robots (`circle_radius_of`), noisy or not."""
    document = circle_document(count, radius=circle_radius_of(count))
    if not noise:
        document['noise'] = {'position_std': 0.0, 'velocity_std': 0.0, 'actuation_std': 0.0}
    return document


def run_team(scenario, method='prvo', observer=None):
    """Run SCENARIO on the in-process engine to its end (planner METHOD); return (row, steps).

    OBSERVER, if given, is called as observer(team, step) after every step. The row's times are
    of the steps alone (`setup_s` is building the team); `step_ms_per_robot_step` and its
    median are each step's `InProcessTeam.do_step` wall time over the team's size,
    `plan_ms_per_robot_step` the agents' planning within it (`StepRecord.plan_ms`).
    """
    values = [planner_values(robot, scenario, method, None) for robot in scenario.robots]
    started = time.perf_counter()
    team = InProcessTeam(scenario, values)
    rule = ArrivalRule.of(scenario)
    setup = time.perf_counter() - started
    count = len(scenario.robots)
    started = time.perf_counter()
    steps, step_ms = [], []
    while not team.finished:
        step_started = time.perf_counter()
        step = team.do_step()
        step_ms.append(1e3 * (time.perf_counter() - step_started) / count)
        steps.append(step)
        if observer is not None:
            observer(team, step)
        if rule.step(step.time, step.states[:, :2]):
            break
    wall = time.perf_counter() - started
    robot_steps = len(steps) * count
    return {
        'robots': count,
        'setup_s': round(setup, 2),
        'wall_s': round(wall, 2),
        'sim_s': round(steps[-1].time, 2),
        'real_time_factor': round(steps[-1].time / wall, 3),
        'steps': len(steps),
        'robot_steps_per_s': round(robot_steps / wall, 1),
        'plan_ms_per_robot_step': round(float(np.mean([step.plan_ms for step in steps])), 3),
        'step_ms_per_robot_step': round(float(np.mean(step_ms)), 3),
        'step_ms_per_robot_step_median': round(float(np.median(step_ms)), 3),
        'all_arrived': rule.all_arrived,
        'collisions': team.world.contact_count,
        'peak_rss_mib': round(peak_rss_kib('self') / KIB_PER_MIB, 1),
    }, steps


class Progress:
    """Prints a team's progress every PROGRESS_EVERY s of simulated time (an observer)."""

    def __init__(self, scenario):
        self.goals = np.array([robot.goal for robot in scenario.robots])
        self.tolerance = scenario.goal_tolerance
        self.started = time.perf_counter()
        self.next = PROGRESS_EVERY

    def __call__(self, team, step):
        """Print a line when STEP reaches the next multiple of PROGRESS_EVERY."""
        if step.time + 1e-9 < self.next:
            return
        self.next += PROGRESS_EVERY
        at_goal = int((np.linalg.norm(step.states[:, :2] - self.goals, axis=1)
                       <= self.tolerance).sum())
        print(f'  {len(self.goals)} robots: {step.time:.1f} s simulated, '
              f'{time.perf_counter() - self.started:.1f} s wall, {at_goal} at their goals, '
              f'{team.world.contact_count} collisions', flush=True)


def peer_circle(count):
    """Return (starts, goals, radii) of the peer circle of COUNT robots (no noise)."""
    document = engine_circle_document(count, noise=False)
    starts = np.array([robot['start'] for robot in document['robots']])
    goals = np.array([robot['goal'] for robot in document['robots']])
    radii = np.array([robot['radius'] for robot in document['robots']])
    return starts, goals, radii


def time_peer(count, dt=0.1):
    """Run ir-sim's RVO on the COUNT circle; return (ms per robot-step (N,), robots arrived).

    Only the planning call is timed (see the module's docstring); None without ir-sim.
    """
    try:
        from irsim.lib.algorithm.rvo import reciprocal_vel_obs
    except ImportError:
        return None
    positions, goals, radii = peer_circle(count)
    velocities = np.zeros_like(positions)
    times = []
    steps = int(math.ceil(4.0 * np.linalg.norm(goals[0] - positions[0]) / PEER_SPEED / dt))
    for _ in range(steps):
        new_velocities = np.zeros_like(velocities)
        for index in range(count):
            to_goal = goals[index] - positions[index]
            distance = float(np.hypot(*to_goal))
            preferred = (to_goal / distance * PEER_SPEED * min(1.0, distance / (
                PEER_APPROACH_DISTANCE)) if distance > 0.1 else np.zeros(2))
            state = [*positions[index], *velocities[index], radii[index], *preferred]
            others = [[*positions[other], *velocities[other], radii[other]]
                      for other in range(count) if other != index]
            started = time.perf_counter()
            velocity = np.array(reciprocal_vel_obs(
                state, others, vxmax=PEER_SPEED, vymax=PEER_SPEED, acce=1.0,
                factor=1.0).cal_vel('rvo'), dtype=float)
            times.append(time.perf_counter() - started)
            speed = float(np.hypot(*velocity))
            new_velocities[index] = velocity if speed <= PEER_SPEED else velocity / speed
        velocities = new_velocities
        positions = positions + dt * velocities
        if np.all(np.linalg.norm(goals - positions, axis=1) < GOAL_TOLERANCE):
            break
    arrived = int((np.linalg.norm(goals - positions, axis=1) < GOAL_TOLERANCE).sum())
    return 1e3 * np.array(times), arrived


# Where a robot-step goes (`--profile`): each phase is the cumulative time of the functions
# (file suffix, name) it names, as the step calls them (a plan request may plan too: whether
# anyone comes to a robot at its goal standing on a condition's edge is a plan, and counts as
# the request's).
PHASES = (
    ('core_ms', (('prvo_planner/core/planner.py', 'plan_velocities'),)),
    ('requests_ms', (('prvo_planner/agent.py', 'plan_request'),)),
    ('completions_ms', (('prvo_planner/agent.py', 'complete'),)),
    ('own_odometry_ms', (('prvo_planner/agent.py', 'receive_own'),)),
    ('neighbour_tracks_ms', (('prvo_planner/tracks.py', 'receive'),)),
    ('messages_ms', (('prvo_sim/world_messages.py', 'serialized_odometry'),
                     ('prvo_sim/engine.py', '_decoded'))),
    ('world_ms', (('prvo_sim/world.py', 'step'),)),
    ('announcements_ms', (('prvo_sim/engine.py', '_announce'),
                          ('prvo_sim/engine.py', '_publish_routes'))),
)
STEP = ('prvo_sim/engine.py', 'do_step')


def phase_times(stats, robot_steps):
    """
    Return {phase: profiled ms per robot-step} of a team run's `pstats.Stats` STATS.

    Also 'step_ms' (`InProcessTeam.do_step` whole), 'other_ms' (the step less its phases) and
    'kernels_ms', the self time of the core's compiled kernels (`prvo_planner.bench
    .compiled_kernel`), wherever the step calls them: the team's plan and a request's.
    """
    def cumulative(wanted):
        return sum(
            calls[3] for (filename, _, name), value in stats.stats.items()
            if any(filename.endswith(suffix) and name == function for suffix, function in wanted)
            for (caller_file, _, caller), calls in value[4].items()
            if caller_file.endswith(STEP[0]) and (caller == STEP[1] or caller.startswith('<')))
    per_step = 1e3 / robot_steps
    times = {'step_ms': sum(value[3] for (filename, _, name), value in stats.stats.items()
                            if filename.endswith(STEP[0]) and name == STEP[1]) * per_step}
    for key, wanted in PHASES:
        times[key] = cumulative(wanted) * per_step
    times['other_ms'] = times['step_ms'] - sum(times[key] for key, _ in PHASES)
    times['kernels_ms'] = sum(value[2] for key, value in stats.stats.items()
                              if compiled_kernel(key)) * per_step
    return {key: round(value, 3) for key, value in times.items()}


def profiled_team(scenario):
    """Run SCENARIO under cProfile (CPU time); return its phase row (`phase_times`)."""
    profiler = cProfile.Profile(time.process_time)
    profiler.enable()
    row, _ = run_team(scenario)
    profiler.disable()
    robot_steps = row['steps'] * row['robots']
    return {'robots': row['robots'], 'robot_steps': robot_steps,
            **phase_times(pstats.Stats(profiler), robot_steps)}


def _mean_and_median(values):
    """Return (mean, median) of VALUES, rounded to the microsecond; (None, None) for None."""
    if values is None:
        return None, None
    return round(float(np.mean(values)), 3), round(float(np.median(values)), 3)


def _ratio(numerator, denominator):
    """Return NUMERATOR / DENOMINATOR to two decimals, None if either is None."""
    if numerator is None or denominator is None:
        return None
    return round(numerator / denominator, 2)


def _arrived(positions, goals, tolerance=GOAL_TOLERANCE):
    """Return how many of POSITIONS (N, 2) are within TOLERANCE of their GOALS (N, 2)."""
    return int((np.linalg.norm(positions - goals, axis=1) <= tolerance).sum())


def peer_key(peer):
    """Return the prefix of PEER's keys in a peer row: 'navground-orca' -> 'navground_orca'."""
    return peer.replace('-', '_')


def peer_row(count, out_dir, peers=PEERS, overrides=None):
    """
    Return the peer comparison row of COUNT robots: each of PEERS and PRVO's engine.

    Every planner is summarised alike, by the mean and the median of its ms per robot-step
    (what each times: the module's docstring), and by its robots at their goals at its end;
    crowded steps cost more than open ones, so a mean lies above its median. A peer not in
    PEERS has None. OVERRIDES ({name: value}) are set over PRVO's planner parameters.
    """
    from prvo_sim.bench import walls  # it imports this module: imported when first needed

    scenario = walls.with_planner(
        write_scenario(engine_circle_document(count, noise=False),
                       out_dir / f'peer_circle{count}.yaml'), overrides or {})
    goals = np.array([robot.goal for robot in scenario.robots])
    engine_row, steps = run_team(scenario)
    row = {'robots': count, 'radius_m': circle_radius_of(count)}
    for peer in PEERS:
        times, arrived = None, None
        if peer == 'irsim-rvo' and peer in peers:
            timed = time_peer(count, scenario.dt)
            if timed is not None:
                times, arrived = timed
        elif peer in peers:
            world = walls.peer_world(scenario)
            _, positions, times = walls.peer_trajectory(peer, world)
            arrived = _arrived(positions[-1], world.goals, world.goal_tolerance)
        key = peer_key(peer)
        row[f'{key}_ms_mean'], row[f'{key}_ms_median'] = _mean_and_median(times)
        row[f'{key}_arrived'] = arrived
    row['prvo_plan_ms_mean'], row['prvo_plan_ms_median'] = _mean_and_median(
        np.concatenate([step.plan_ms for step in steps]))
    row['prvo_step_ms_mean'] = engine_row['step_ms_per_robot_step']
    row['prvo_step_ms_median'] = engine_row['step_ms_per_robot_step_median']
    for kind in ('plan', 'step'):
        for summary in ('mean', 'median'):
            row[f'prvo_{kind}_over_irsim_{summary}'] = _ratio(
                row[f'prvo_{kind}_ms_{summary}'], row[f'irsim_rvo_ms_{summary}'])
    row['prvo_arrived'] = _arrived(steps[-1].states[:, :2], goals, scenario.goal_tolerance)
    row['prvo_collisions'] = engine_row['collisions']
    return row


def peer_table(rows):
    """Return the Markdown tables of the peer ROWS: ms per robot-step, then arrivals."""
    def pair(row, first, second, form):
        if row[first] is None:
            return 'n/a'
        return f'{form.format(row[first])} / {form.format(row[second])}'

    planners = [(peer_key(peer), PEER_HEADERS[peer]) for peer in PEERS]
    planners += [('prvo_plan', 'PRVO plan'), ('prvo_step', 'PRVO step')]
    timed = [{'robots': row['robots'], 'radius_m': row['radius_m'],
              **{key: pair(row, f'{key}_ms_mean', f'{key}_ms_median', '{:.3f}')
                 for key, _ in planners},
              **{f'{kind}_ratio': pair(row, f'prvo_{kind}_over_irsim_mean',
                                       f'prvo_{kind}_over_irsim_median', '{:.2f}')
                 for kind in ('plan', 'step')}} for row in rows]
    columns = [('robots', 'robots'), ('radius_m', 'radius m'),
               *((key, f'{header} ms') for key, header in planners),
               ('plan_ratio', 'PRVO plan / ir-sim'), ('step_ratio', 'PRVO step / ir-sim')]
    arrivals = [{'robots': row['robots'],
                 **{key: None if row[f'{key}_arrived'] is None
                    else f"{row[f'{key}_arrived']}/{row['robots']}"
                    for key in [*(peer_key(peer) for peer in PEERS), 'prvo']},
                 'prvo_collisions': row['prvo_collisions']} for row in rows]
    arrival_columns = [('robots', 'robots'),
                       *((peer_key(peer), PEER_HEADERS[peer]) for peer in PEERS),
                       ('prvo', 'PRVO'), ('prvo_collisions', 'PRVO collisions')]
    return ('ms per robot-step, mean / median (ratios: of the means / of the medians):\n'
            + table(timed, columns) + '\n\nRobots at their goals at the end:\n'
            + table(arrivals, arrival_columns))


def report(rows, columns, notes, json_path):
    """Print ROWS as a table of COLUMNS [(key, header)], then NOTES; write both to JSON_PATH.

    JSON_PATH (a pathlib.Path; None: none) gets {'runs': ROWS, 'notes': NOTES}.
    """
    print(table(rows, columns))
    for note in notes:
        print(f'note: {note}')
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps({'runs': rows, 'notes': notes}, indent=2) + '\n')


def table(rows, columns):
    """Return a Markdown table of ROWS with COLUMNS [(key, header)]."""
    lines = ['| ' + ' | '.join(header for _, header in columns) + ' |',
             '|' + '---|' * len(columns)]
    for row in rows:
        cells = ['n/a' if row.get(key) is None else ('yes' if row[key] is True else 'no'
                 if row[key] is False else str(row[key])) for key, _ in columns]
        lines.append('| ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


TEAM_COLUMNS = (('robots', 'robots'), ('radius_m', 'radius m'), ('setup_s', 'setup s'),
                ('wall_s', 'wall s'), ('sim_s', 'sim s'),
                ('real_time_factor', 'real-time factor'), ('steps', 'steps'),
                ('robot_steps_per_s', 'robot-steps/s'),
                ('plan_ms_per_robot_step', 'plan ms per robot-step'),
                ('step_ms_per_robot_step', 'step ms per robot-step'),
                ('all_arrived', 'all arrived'), ('collisions', 'collisions'),
                ('peak_rss_mib', 'peak RSS MiB'))
PHASE_COLUMNS = (('robots', 'robots'), ('robot_steps', 'robot-steps'),
                 ('step_ms', 'step ms'), ('core_ms', 'core plan'),
                 ('kernels_ms', 'compiled kernels (in plans)'),
                 ('requests_ms', 'plan requests'), ('completions_ms', 'completions'),
                 ('own_odometry_ms', 'own odometry'), ('neighbour_tracks_ms', 'neighbour tracks'),
                 ('messages_ms', 'messages'), ('world_ms', 'world'),
                 ('announcements_ms', 'announcements, routes'), ('other_ms', 'other'))

def build_parser():
    """Return the command-line parser of the engine benchmark."""
    parser = argparse.ArgumentParser(
        prog='python -m prvo_sim.bench.engine',
        description='Benchmark the in-process engine on circles of robots, and peers beside it.')
    parser.add_argument('--robots', type=int, nargs='*', default=list(DEFAULT_TEAM_SIZES),
                        help='team sizes, under noise (default: 8 16 48 100; none: skip)')
    parser.add_argument('--peer-robots', type=int, nargs='*', default=list(DEFAULT_PEER_SIZES),
                        help='team sizes of the peer comparison (default: 10 20 50; none: skip)')
    parser.add_argument('--peers', nargs='*', default=list(PEERS), choices=PEERS,
                        help='peers to run when importable (default: all; none: --peers)')
    parser.add_argument('--planner', nargs='*', default=[], metavar='NAME=VALUE',
                        help="planner parameters of every PRVO robot over the circle's "
                             '(values read as YAML)')
    parser.add_argument('--json', type=pathlib.Path, default=None,
                        help='also write {"teams": [...], "peers": [...], "phases": [...], '
                             '"notes": [...]} to this file')
    parser.add_argument('--profile', action='store_true',
                        help="also run each team under cProfile and tabulate a robot-step's "
                             'phases, profiled CPU ms per robot-step')
    parser.add_argument('--out', type=pathlib.Path, default=pathlib.Path('results/bench_engine'),
                        help='folder of the scenarios and trajectories '
                             '(default: results/bench_engine)')
    return parser


def print_results(teams, phases, peers, notes, json_path):
    """Print the tables of TEAMS, PHASES and PEERS, then NOTES; write them all to JSON_PATH."""
    if teams:
        print(table(teams, TEAM_COLUMNS))
    if phases:
        print()
        print('Profiled CPU ms per robot-step:')
        print(table(phases, PHASE_COLUMNS))
    if peers:
        print()
        print(peer_table(peers))
    for note in notes:
        print(f'note: {note}')
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(json.dumps({'teams': teams, 'peers': peers, 'phases': phases,
                                         'notes': notes}, indent=2) + '\n')


def main(argv=None):
    """Run the engine benchmark's command line; return the exit code."""
    from prvo_sim.bench import walls  # it imports this module: imported when first needed

    parser = build_parser()
    options = parser.parse_args(sys.argv[1:] if argv is None else argv)
    for count in [*options.robots, *options.peer_robots]:
        if count < 2:
            print(f'prvo_sim.bench.engine: error: --robots: {count} is not a team (at least 2)',
                  file=sys.stderr)
            return 2
    try:
        overrides = walls.planner_overrides(options.planner)
    except ValueError as error:
        print(f'prvo_sim.bench.engine: error: {error}', file=sys.stderr)
        return 2
    notes = []
    peer_names = (walls.importable_peers(options.peers, notes, PEER_PACKAGES)
                  if options.peer_robots else [])
    teams, peers, phases = [], [], []
    try:
        for count in sorted(options.robots):
            scenario = walls.with_planner(write_scenario(
                engine_circle_document(count), options.out / f'circle{count}.yaml'), overrides)
            row, steps = run_team(scenario, observer=Progress(scenario))
            write_trajectories_csv(
                options.out / f'circle{count}_trajectories.csv',
                np.array([step.time for step in steps]),
                [robot.name for robot in scenario.robots],
                np.array([step.states for step in steps]),
                np.array([step.commands for step in steps]))
            teams.append({'robots': row['robots'], 'radius_m': circle_radius_of(count), **row})
            print(f'{count} robots: {row["wall_s"]} s wall for {row["sim_s"]} s simulated, all '
                  f'arrived {row["all_arrived"]}, {row["collisions"]} collisions', flush=True)
            if options.profile:
                phases.append(profiled_team(scenario))
        for count in options.peer_robots:
            peers.append(peer_row(count, options.out, peer_names, overrides))
            print(f'peers, {count} robots: done', flush=True)
    except KeyboardInterrupt:
        print('prvo_sim.bench.engine: interrupted; the tables hold what completed',
              file=sys.stderr)
        print_results(teams, phases, peers, notes, options.json)
        return 130
    print_results(teams, phases, peers, notes, options.json)
    return 0 if all(row['all_arrived'] for row in teams) else 1


if __name__ == '__main__':
    sys.exit(main())
