"""Engine benchmark: teams of 8 to 96 robots on the in-process engine, and a peer beside them.

    python -m prvo_sim.bench.engine [--robots 8 16 48 96] [--peer-robots 10 20] [--json PATH]
                                    [--out DIR] [--profile]

For each team size N it runs the team benchmark's circle (`team.circle_document`: N
robots swapping antipodal points under noise, PRVO at eta 0.8) on the in-process engine to
completion and prints a Markdown table row: wall time, simulated time, steps, robot-steps per
wall second, the planners' wall time per robot-step (the team is planned in one call, so each
robot is charged an equal share), arrivals, collisions and the process's peak RSS after the run
(VmHWM: it only grows, so run sizes in increasing order). Trajectories go to DIR.

With `--peer-robots`, the same command also times a peer on the same circles without noise:
ir-sim's numpy RVO (`irsim.lib.algorithm.rvo`), each robot each step building
`reciprocal_vel_obs` over every other robot and calling `cal_vel('rvo')`, as ir-sim's own
behaviour does; and PRVO's engine on the same circle. Both are summarised by the mean and the
median of their ms per robot-step, and their ratios. ir-sim is not a dependency of prvo:
install it beside it (`pip install ir-sim`) to measure it; without it the peer cells say n/a.

With `--profile` each team runs under cProfile (CPU time) and a second table says where a
robot-step goes: the core's team plan (`plan_velocities`), and around it the agents' plan
requests (beliefs, preferences, rules), their completions (commands), their own odometry and
the neighbours' tracks (Kalman updates), the odometry messages (serialized and decoded as a
subscriber gets them), the world's step and the announcements and routes; the rest is the
step's own bookkeeping. Profiled times are 1.3-2x the plain ones: compare within the table.

Exit codes: 0 every run completed, 1 a run did not, 2 bad input, 130 when interrupted.
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

from prvo_sim.bench.team import circle_document, peak_rss_kib, write_scenario
from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.outputs import write_trajectories_csv
from prvo_sim.runner.session import ArrivalRule, planner_values

DEFAULT_TEAM_SIZES = (8, 16, 48, 96)
DEFAULT_PEER_SIZES = (10, 20)
KIB_PER_MIB = 1024.0
PEER_SPEED = 1.0  # m/s, the circle's max speed
PEER_APPROACH_DISTANCE = 1.0  # m: the peer's preferred speed slows linearly over the last metre


def run_team(scenario, method='prvo', observer=None):
    """Run SCENARIO on the in-process engine to its end (planner METHOD); return (row, steps).

    OBSERVER, if given, is called as observer(team, step) after every step.
    """
    values = [planner_values(robot, scenario, method, None) for robot in scenario.robots]
    team = InProcessTeam(scenario, values)
    rule = ArrivalRule.of(scenario)
    started = time.perf_counter()
    steps = []
    while not team.finished:
        step = team.do_step()
        steps.append(step)
        if observer is not None:
            observer(team, step)
        if rule.step(step.time, step.states[:, :2]):
            break
    wall = time.perf_counter() - started
    count = len(scenario.robots)
    robot_steps = len(steps) * count
    return {
        'robots': count,
        'wall_s': round(wall, 2),
        'sim_s': round(steps[-1].time, 2),
        'steps': len(steps),
        'robot_steps_per_s': round(robot_steps / wall, 1),
        'plan_ms_per_robot_step': round(float(np.mean([step.plan_ms for step in steps])), 3),
        'all_arrived': rule.all_arrived,
        'collisions': team.world.contact_count,
        'peak_rss_mib': round(peak_rss_kib('self') / KIB_PER_MIB, 1),
    }, steps


def peer_circle(count):
    """Return (starts, goals, radii) of the peer circle: the team benchmark's, without noise."""
    document = circle_document(count)
    starts = np.array([robot['start'] for robot in document['robots']])
    goals = np.array([robot['goal'] for robot in document['robots']])
    radii = np.array([robot['radius'] for robot in document['robots']])
    return starts, goals, radii


def time_peer(count, dt=0.1):
    """Return ir-sim's RVO's ms per robot-step on the COUNT circle, (N,); None without ir-sim."""
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
        if np.all(np.linalg.norm(goals - positions, axis=1) < 0.2):
            break
    return 1e3 * np.array(times)


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

    Also 'step_ms' (`InProcessTeam.do_step` whole) and 'other_ms' (the step less its phases).
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


def peer_row(count, out_dir):
    """
    Return the peer comparison row of COUNT robots: ir-sim's RVO and PRVO's engine.

    Both sides are summarised alike, by the mean and the median of their ms per robot-step:
    crowded steps cost PRVO more than open ones, so its mean lies above its median.
    """
    document = circle_document(count)
    document['noise'] = {'position_std': 0.0, 'velocity_std': 0.0, 'actuation_std': 0.0}
    scenario = write_scenario(document, out_dir / f'peer_circle{count}.yaml')
    engine_row, steps = run_team(scenario)
    peer_mean, peer_median = _mean_and_median(time_peer(count))
    prvo_mean, prvo_median = _mean_and_median(np.concatenate([step.plan_ms for step in steps]))
    return {'robots': count, 'irsim_rvo_ms_mean': peer_mean, 'irsim_rvo_ms_median': peer_median,
            'prvo_ms_mean': prvo_mean, 'prvo_ms_median': prvo_median,
            'ratio_mean': None if peer_mean is None else round(prvo_mean / peer_mean, 1),
            'ratio_median': None if peer_median is None else round(prvo_median / peer_median, 1),
            'prvo_all_arrived': engine_row['all_arrived'],
            'prvo_collisions': engine_row['collisions']}


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


TEAM_COLUMNS = (('robots', 'robots'), ('wall_s', 'wall s'), ('sim_s', 'sim s'),
                ('steps', 'steps'), ('robot_steps_per_s', 'robot-steps/s'),
                ('plan_ms_per_robot_step', 'plan ms per robot-step'),
                ('all_arrived', 'all arrived'), ('collisions', 'collisions'),
                ('peak_rss_mib', 'peak RSS MiB'))
PHASE_COLUMNS = (('robots', 'robots'), ('robot_steps', 'robot-steps'),
                 ('step_ms', 'step ms'), ('core_ms', 'core plan'),
                 ('requests_ms', 'plan requests'), ('completions_ms', 'completions'),
                 ('own_odometry_ms', 'own odometry'), ('neighbour_tracks_ms', 'neighbour tracks'),
                 ('messages_ms', 'messages'), ('world_ms', 'world'),
                 ('announcements_ms', 'announcements, routes'), ('other_ms', 'other'))
PEER_COLUMNS = (('robots', 'robots'), ('irsim_rvo_ms_mean', 'ir-sim RVO ms, mean'),
                ('irsim_rvo_ms_median', 'ir-sim RVO ms, median'),
                ('prvo_ms_mean', 'PRVO ms, mean'), ('prvo_ms_median', 'PRVO ms, median'),
                ('ratio_mean', 'ratio of means'), ('ratio_median', 'ratio of medians'),
                ('prvo_all_arrived', 'PRVO all arrived'), ('prvo_collisions', 'PRVO collisions'))


def build_parser():
    """Return the command-line parser of the engine benchmark."""
    parser = argparse.ArgumentParser(
        prog='python -m prvo_sim.bench.engine',
        description='Benchmark the in-process engine on circles of robots.')
    parser.add_argument('--robots', type=int, nargs='+', default=list(DEFAULT_TEAM_SIZES),
                        help='team sizes (default: 8 16 48 96)')
    parser.add_argument('--peer-robots', type=int, nargs='*', default=list(DEFAULT_PEER_SIZES),
                        help='team sizes of the peer comparison (default: 10 20; none: skip)')
    parser.add_argument('--json', type=pathlib.Path, default=None,
                        help='also write {"teams": [...], "peers": [...]} to this file')
    parser.add_argument('--profile', action='store_true',
                        help="also run each team under cProfile and tabulate a robot-step's "
                             'phases, profiled CPU ms per robot-step')
    parser.add_argument('--out', type=pathlib.Path, default=pathlib.Path('results/bench_engine'),
                        help='folder of the scenarios and trajectories '
                             '(default: results/bench_engine)')
    return parser


def main(argv=None):
    """Run the engine benchmark's command line; return the exit code."""
    parser = build_parser()
    options = parser.parse_args(sys.argv[1:] if argv is None else argv)
    for count in [*options.robots, *options.peer_robots]:
        if count < 2:
            print(f'prvo_sim.bench.engine: error: --robots: {count} is not a team (at least 2)',
                  file=sys.stderr)
            return 2
    teams, peers, phases = [], [], []
    try:
        for count in sorted(options.robots):
            scenario = write_scenario(circle_document(count),
                                      options.out / f'circle{count}.yaml')
            row, steps = run_team(scenario)
            write_trajectories_csv(
                options.out / f'circle{count}_trajectories.csv',
                np.array([step.time for step in steps]),
                [robot.name for robot in scenario.robots],
                np.array([step.states for step in steps]),
                np.array([step.commands for step in steps]))
            teams.append(row)
            print(f'{count} robots: {row["wall_s"]} s wall, all arrived '
                  f'{row["all_arrived"]}, {row["collisions"]} collisions', flush=True)
            if options.profile:
                phases.append(profiled_team(scenario))
        for count in options.peer_robots:
            peers.append(peer_row(count, options.out))
    except KeyboardInterrupt:
        print('prvo_sim.bench.engine: interrupted', file=sys.stderr)
        return 130
    print(table(teams, TEAM_COLUMNS))
    if phases:
        print()
        print('Profiled CPU ms per robot-step:')
        print(table(phases, PHASE_COLUMNS))
    if peers:
        print()
        print(table(peers, PEER_COLUMNS))
    if options.json is not None:
        options.json.parent.mkdir(parents=True, exist_ok=True)
        options.json.write_text(json.dumps({'teams': teams, 'peers': peers, 'phases': phases},
                                           indent=2) + '\n')
    return 0 if all(row['all_arrived'] for row in teams) else 1


if __name__ == '__main__':
    sys.exit(main())
