"""Doors benchmark: a robot alone in a door or a corridor it fits, three position stds to spare.

    python -m prvo_sim.bench.doors [--radii 0.2 0.25 0.3] [--stds 0.02 0.05]
                                   [--etas 0.95 0.99] [--angles 0 45 | --corridor]
                                   [--seeds 10] [--json PATH]
    python -m prvo_sim.bench.doors --monte-carlo N [--samples 20000]

Each case is a wall along x = 0 (THICKNESS thick, 2 WALL_HALF long) with a door centred at the
origin whose clear width (between the jambs' surfaces) is ``2 r + 6 sigma_p``; one robot of
radius r, noise sigma_p on position, velocity and actuation, the planner's defaults but
``eta``. It starts APPROACH from the door's centre at the angle [deg] from the wall's normal
and heads for the point opposite. Every case runs on the in-process engine for DURATION per
seed (consecutive seeds from 1). Per case: the robots through (centre past the wall's far face
by its radius), the wall contacts, the least clearance of a robot from the real walls (the
simulator's, minus the radius) and the median time through.

With ``--corridor`` each case is instead an L-shaped corridor of the same clear width, closed at
both ends, whose centre line runs LEG east from the start, then LEG north to the goal (10 m);
the robot is through when it arrives (within the goal tolerance), DURATION_CORRIDOR at most.

With ``--monte-carlo N`` it plans N seeded approaches to doors (``door_approach``) and samples
the executed motion as the planner's model states it (the belief's position, then a fresh
execution error every control period, held for the period) over the obstacle horizon: per
approach the probability the plan states, the share of sampled paths clear of every jamb
segment (each segment is an obstacle of its own; the share for the worst one), and quantiles
of the least clearance from the jambs [m].

Exit codes: 0 every robot through without a contact (every Monte Carlo share at least the
stated probability, within 4 binomial stds), 1 otherwise, 2 bad input.
"""

import argparse
import json
import math
import pathlib
import sys
import tempfile

import numpy as np

from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity
from prvo_planner.core.obstacles import StaticObstacles
from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import load_scenario

THICKNESS = 0.1
WALL_HALF = 4.0
APPROACH = 3.0
DURATION = 30.0
LEG = 5.0
DURATION_CORRIDOR = 60.0


def _scenario(name, description, duration, walls, start, goal, radius, noise, eta):
    """Return the YAML text of one robot alone among WALLS (segments [[x, y], [x, y]])."""
    planner = '' if eta is None else f'planner:\n  eta: {eta}\n'
    lines = ''.join(f'  - line: [[{a[0]}, {a[1]}], [{b[0]}, {b[1]}]]\n'
                    f'    thickness: {THICKNESS}\n' for a, b in walls)
    return f"""name: {name}
description: {description}
seed: 1
dt: 0.1
duration: {duration}
goal_tolerance: 0.2
noise:
  position_std: {noise}
  velocity_std: {noise}
  actuation_std: {noise}
{planner}walls:
{lines}robots:
  - name: robot_0
    start: [{start[0]:.6f}, {start[1]:.6f}]
    goal: [{goal[0]:.6f}, {goal[1]:.6f}]
    radius: {radius}
    max_speed: 1.0
"""


def door_scenario(radius, clear_width, noise, angle=0.0, eta=None):
    """Return the YAML text of one robot at a door of CLEAR_WIDTH [m]; ANGLE [rad].

    The jambs are walls along x = 0 whose rounded tips are the door's edges.
    """
    tip = 0.5 * clear_width + 0.5 * THICKNESS
    heading = np.array([math.cos(angle), math.sin(angle)])
    return _scenario('door', f'One robot, one door of clear width {clear_width:.3f} m.',
                     DURATION, [((0.0, WALL_HALF), (0.0, tip)), ((0.0, -WALL_HALF), (0.0, -tip))],
                     -APPROACH * heading, APPROACH * heading, radius, noise, eta)


def corridor_scenario(radius, clear_width, noise, eta=None):
    """Return the YAML text of one robot in an L-shaped corridor of CLEAR_WIDTH [m].

    The centre line runs from the start (0, 0) LEG east, then LEG north to the goal. The ends
    are closed half a width behind the start and the goal: open, the way round the outside of
    the bend would be shorter than the corridor, and the route would take it.
    """
    offset = 0.5 * clear_width + 0.5 * THICKNESS
    outer, inner = LEG + offset, LEG - offset
    walls = [((-offset, -offset), (outer, -offset)), ((outer, -offset), (outer, outer)),
             ((-offset, offset), (inner, offset)), ((inner, offset), (inner, outer)),
             ((-offset, -offset), (-offset, offset)), ((inner, outer), (outer, outer))]
    return _scenario('corridor', 'One robot, an L-shaped corridor of clear width '
                     f'{clear_width:.3f} m.', DURATION_CORRIDOR, walls, (0.0, 0.0), (LEG, LEG),
                     radius, noise, eta)


def door_approach(seed, horizon=2.0):
    """Return a seeded approach to a door: ego, config, obstacles, heading, grown, description.

    Radius 0.2-0.3, sigma 0.02 or 0.05 on the belief's position and the execution, a door
    2 r + (6, 8 or 12) sigma wide, its jambs capsules THICKNESS thick (odd seeds) or frames
    (the four edges of a THICKNESS deep block, as a map's cells give them), approached at up
    to 45 degrees, 0.2-1.5 m from the door's centre, 0.2-1 m/s, eta 0.9, 0.95 or 0.99.
    ``grown`` is the radius plus the jambs' half-width.
    """
    rng = np.random.default_rng(seed)
    radius = float(rng.choice([0.2, 0.25, 0.3]))
    sigma = float(rng.choice([0.02, 0.05]))
    width = 2.0 * radius + float(rng.choice([6.0, 8.0, 12.0])) * sigma
    angle = rng.uniform(-math.pi / 4.0, math.pi / 4.0)
    heading = np.array([math.cos(angle), math.sin(angle)])
    distance = rng.uniform(0.2, 1.5)
    position = -distance * heading + [0.0, rng.normal(0.0, sigma)]
    half, depth = 0.5 * width, 0.5 * THICKNESS
    if seed % 2:
        segments = [[[0.0, -WALL_HALF], [0.0, -half - depth]],
                    [[0.0, half + depth], [0.0, WALL_HALF]]]
        half_widths = [depth, depth]
    else:
        segments = []
        for sign in (-1.0, 1.0):
            corners = [[-depth, sign * half], [depth, sign * half], [depth, sign * WALL_HALF],
                       [-depth, sign * WALL_HALF]]
            segments += [[corners[i], corners[(i + 1) % 4]] for i in range(4)]
        half_widths = [0.0] * len(segments)
    speed = rng.uniform(0.2, 1.0)
    ego = AgentBelief(position, speed * heading, sigma ** 2 * np.eye(4), radius)
    config = PlannerConfig(eta=float(rng.choice([0.9, 0.95, 0.99])),
                           actuation_cov=sigma ** 2 * np.eye(2), obstacle_horizon=horizon,
                           certificate='certified', seed=seed)
    door = StaticObstacles(np.array(segments), np.array(half_widths), np.zeros((0, 2)),
                           np.zeros(0))
    description = {'seed': seed, 'radius': radius, 'sigma': sigma, 'door': width,
                   'jambs': 'capsules' if seed % 2 else 'frames',
                   'angle_deg': math.degrees(angle), 'distance': distance, 'speed': speed,
                   'eta': config.eta}
    return ego, config, door, heading, radius + half_widths[0], description


def _segment_distances(points, start, end):
    """Distance of POINTS (..., 2) from the segment [START, END]."""
    along = end - start
    fraction = np.clip(((points - start) @ along) / (along @ along), 0.0, 1.0)
    return np.linalg.norm(points - (start + fraction[..., None] * along), axis=-1)


def executed_clearances(rng, ego, velocity, config, door, grown, samples, per_period=5):
    """Sample the executed motion over the horizon; return the least clearances (samples, N).

    The belief's position, then the command VELOCITY with a fresh error ``N(0, S_a)`` every
    control period, held for the period (PER_PERIOD points a period), over the obstacle
    horizon rounded up to whole periods; per jamb segment the least distance minus GROWN.
    """
    period = config.control_period
    periods = math.ceil(config.obstacle_horizon / period - 1e-9)
    start = rng.multivariate_normal(ego.position, ego.covariance[:2, :2], samples)
    noise = rng.multivariate_normal(np.zeros(2), config.actuation_cov, (samples, periods))
    times = np.linspace(0.0, periods * period, periods * per_period + 1)
    index = np.minimum((times / period + 1e-9).astype(int), periods - 1)
    walked = np.concatenate([np.zeros((samples, 1, 2)), np.cumsum(period * noise, axis=1)],
                            axis=1)[:, index]
    paths = (start[:, None, :] + times[None, :, None] * velocity + walked
             + (times - index * period)[None, :, None] * noise[:, index])
    return np.stack([_segment_distances(paths, start_, end).min(axis=1) - grown
                     for start_, end in door.segments], axis=1)


def monte_carlo(approaches, samples):
    """Plan and sample APPROACHES seeded approaches; print the table; return whether all hold."""
    print('| seed | r | sigma | door [m] | jambs | angle [deg] | from [m] | speed [m/s] | eta '
          '| stated | sampled clear (worst segment) | least clearance 1% / 5% / 50% [m] |')
    print('|---|---|---|---|---|---|---|---|---|---|---|---|')
    holds = True
    for seed in range(approaches):
        ego, config, door, heading, grown, case = door_approach(seed)
        result = plan_velocity(ego, [], heading, config, obstacles=door)
        clearances = executed_clearances(np.random.default_rng(10_000 + seed), ego,
                                         result.velocity, config, door, grown, samples)
        stated = result.obstacle_probability
        worst = float((clearances >= 0.0).mean(axis=0).min())
        holds &= worst >= stated - 4.0 * math.sqrt(max(stated * (1.0 - stated), 1e-4) / samples)
        quantiles = np.quantile(clearances.min(axis=1), [0.01, 0.05, 0.5])
        print(f"| {seed} | {case['radius']:.2f} | {case['sigma']:.2f} | {case['door']:.2f} "
              f"| {case['jambs']} | {case['angle_deg']:+.0f} | {case['distance']:.2f} "
              f"| {case['speed']:.2f} | {case['eta']:.2f} | {stated:.4f} | {worst:.4f} "
              f"| {quantiles[0]:+.3f} / {quantiles[1]:+.3f} / {quantiles[2]:+.3f} |",
              flush=True)
    return holds


def past_the_door(scenario, state):
    """Whether the ground-truth STATE's centre is past the wall's far face by the radius."""
    return state[0] > 0.5 * THICKNESS + scenario.robots[0].radius


def at_the_goal(scenario, state):
    """Whether the ground-truth STATE's centre is within the goal tolerance."""
    return np.linalg.norm(state[:2] - scenario.robots[0].goal) <= scenario.goal_tolerance


def run_alone(path, seed, through):
    """Run the scenario file PATH once in process: (time through or None, contacts, clearance).

    The clearance is the least of the robot's [m]. Through: ``THROUGH(scenario, state)`` of the
    ground-truth state planned on (``past_the_door``, ``at_the_goal``); the run stops there.
    """
    scenario = load_scenario(path, seed=seed)
    values = [planner_values(robot, scenario, 'prvo', None) for robot in scenario.robots]
    team = InProcessTeam(scenario, values, seed=seed)
    radius = scenario.robots[0].radius
    world = team.world
    contacts, clearance = 0, math.inf
    while not team.finished:
        step = team.do_step()
        contacts += len(world.last_wall_contacts)
        clearance = min(clearance, float(world.static_world.clearance(
            world.positions[:1])[0]) - radius)
        if through(scenario, step.states[0]):
            return step.time, contacts, clearance
    return None, contacts, clearance


def run_case(folder, radius, sigma, eta, angle_deg, seeds):
    """Run one case over SEEDS; return its row (a dict). ANGLE_DEG None: the L corridor."""
    width = 2.0 * radius + 6.0 * sigma
    path = pathlib.Path(folder) / f'case_{radius}_{sigma}_{eta}_{angle_deg}.yaml'
    if angle_deg is None:
        text, through = corridor_scenario(radius, width, sigma, eta), at_the_goal
    else:
        text = door_scenario(radius, width, sigma, math.radians(angle_deg), eta)
        through = past_the_door
    path.write_text(text)
    runs = [run_alone(path, seed, through) for seed in seeds]
    times = [through for through, _, _ in runs if through is not None]
    return {'radius': radius, 'sigma_p': sigma, 'eta': eta, 'angle_deg': angle_deg,
            'clear_width': width, 'seeds': len(runs), 'through': len(times),
            'contacts': sum(contacts for _, contacts, _ in runs),
            'min_clearance': min(clearance for _, _, clearance in runs),
            'median_time': float(np.median(times)) if times else None}


def _header(corridor):
    """Return the table's header (two lines) for the corridor or the doors."""
    columns = (['r [m]', 'sigma_p [m]', 'corridor [m]', 'eta', 'arrived'] if corridor
               else ['r [m]', 'sigma_p [m]', 'door [m]', 'eta', 'angle [deg]', 'through'])
    columns += ['contacts', 'least clearance [m]',
                f'median time {"to the goal" if corridor else "through"} [s]']
    return f"| {' | '.join(columns)} |\n|{'---|' * len(columns)}"


def _row(row):
    time_through = 'n/a' if row['median_time'] is None else f"{row['median_time']:.1f}"
    angle = '' if row['angle_deg'] is None else f"| {row['angle_deg']:g} "
    return (f"| {row['radius']:.2f} | {row['sigma_p']:.2f} | {row['clear_width']:.2f} "
            f"| {row['eta']:.2f} {angle}| {row['through']}/{row['seeds']} "
            f"| {row['contacts']} | {row['min_clearance']:.3f} | {time_through} |")


def main(argv=None):
    """Run the sweep; print its table (Markdown); return the exit code."""
    parser = argparse.ArgumentParser(prog='python -m prvo_sim.bench.doors',
                                     description=__doc__.split('\n')[0])
    parser.add_argument('--radii', type=float, nargs='+', default=[0.2, 0.25, 0.3])
    parser.add_argument('--stds', type=float, nargs='+', default=[0.02, 0.05])
    parser.add_argument('--etas', type=float, nargs='+', default=[0.95, 0.99])
    passage = parser.add_mutually_exclusive_group()
    passage.add_argument('--angles', type=float, nargs='+', default=[0.0, 45.0])
    passage.add_argument('--corridor', action='store_true')
    parser.add_argument('--seeds', type=int, default=10)
    parser.add_argument('--json', type=pathlib.Path, default=None)
    parser.add_argument('--monte-carlo', type=int, default=None, metavar='N')
    parser.add_argument('--samples', type=int, default=20000)
    try:
        options = parser.parse_args(argv)
    except SystemExit as exit_:
        return 2 if exit_.code else 0
    if options.seeds < 1 or options.samples < 1:
        print('--seeds and --samples must be at least 1', file=sys.stderr)
        return 2
    if options.monte_carlo is not None:
        return 0 if monte_carlo(options.monte_carlo, options.samples) else 1
    print(_header(options.corridor))
    angles = [None] if options.corridor else options.angles
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for radius in options.radii:
            for sigma in options.stds:
                for eta in options.etas:
                    for angle in angles:
                        rows.append(run_case(folder, radius, sigma, eta, angle,
                                             range(1, options.seeds + 1)))
                        print(_row(rows[-1]), flush=True)
    if options.json is not None:
        options.json.write_text(json.dumps(rows, indent=2))
    return 0 if all(row['through'] == row['seeds'] and row['contacts'] == 0
                    for row in rows) else 1


if __name__ == '__main__':
    sys.exit(main())
