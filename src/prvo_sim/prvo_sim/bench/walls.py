"""Wall benchmark: prvo and its peers on the same worlds of walls and obstacles.

    python -m prvo_sim.bench.walls [--scenarios corridor8 doorway8 pillars12] [--seeds 1]
                                   [--methods prvo rvo inflate] [--peers rvo2-orca ...]
                                   [--planner NAME=VALUE ...] [--json PATH]

Each scenario is read through the scenario loader (radii, max speeds, starts, goals, dt,
duration, goal tolerance, walls and obstacles) and run:

* by prvo on the in-process engine, for each of `--methods`: once without noise and over
  `--seeds` consecutive seeds from the scenario's with its noise (one row, summed over the
  seeds: arrivals and contacts added up, the worst makespan, the least separations);
* noise-free, by the peers that are importable: RVO2's ORCA (`pyrvo`: every wall, polygon and
  disc as an RVO2 obstacle, a counter-clockwise polygon; a wall as the rectangle around it, at
  least THIN_WALL_WIDTH wide, a disc as the circumscribed DISC_SIDES-gon) and navground's ORCA
  and HL (`navground`: the same polygons' edges as line-segment walls, discs as disc
  obstacles), each in its own simulator. Neither is a dependency of prvo: a peer that is not
  importable is skipped with one line saying so.

`--planner NAME=VALUE` sets a planner parameter of every prvo robot over the scenario's (each
value read as YAML: `--planner keep_right=0 eta=0.95 certificate=certified`), for ablations and
to run a shipped world at the planner's defaults.

The peers plan with `bench.team.PEER_TIME_HORIZON` against robots and prvo's default
`obstacle_horizon` against walls, and head for their goals at full speed, slowing over the last
APPROACH_TIME as the planner's agent does. Every row is measured from its trajectory by the
runner's own metrics: arrivals (a robot's first time within the goal tolerance) and the makespan,
the least robot-robot separation (centre distance minus the radii) and robot-robot contacts, the
least wall clearance (`StaticWorld.clearance` minus the radius) and wall contacts (clearance at
most the contact tolerance), the planning time per robot-step [ms of wall time: prvo's agents'
share of the team's planning, RVO2's `doStep`, navground's `World.update` with its sensing], and
the stalls by the planner's rule (`prvo_planner.stalls`: a robot away from its goal that gains less
than 0.5 m toward it in 10 s), the longest stall [s] and the longest time a robot stayed within 0.5
m of one spot away from its goal [s].

Exit codes: 0 every prvo robot (method prvo) arrived, 1 one did not, 2 bad input, 130 when
interrupted.
"""

import argparse
import dataclasses
import importlib
import math
import pathlib
import sys
import time

import numpy as np
import yaml

from prvo_planner.parameters import DEFAULTS, check_parameter
from prvo_planner.stalls import SUMMARY_COLUMNS, trajectory_stalls
from prvo_sim.bench.crowds import preferred_velocities
from prvo_sim.bench.engine import report, run_team
from prvo_sim.bench.team import PEER_TIME_HORIZON
from prvo_sim.metrics import run_metrics, wall_metrics
from prvo_sim.scenario import NoiseSpec, find_scenario, load_scenario

DEFAULT_SCENARIOS = ('corridor8', 'doorway8', 'pillars12')
METHODS = ('prvo', 'rvo', 'inflate')
PEERS = ('rvo2-orca', 'navground-orca', 'navground-hl')
PEER_PACKAGES = {'rvo2-orca': 'pyrvo', 'navground-orca': 'navground',
                 'navground-hl': 'navground'}
# navground-hrvo is not among PEERS: the engine benchmark runs it (`bench.engine`).
NAVGROUND_BEHAVIORS = {'navground-orca': 'ORCA', 'navground-hrvo': 'HRVO', 'navground-hl': 'HL'}
# A wall of no thickness is given to RVO2 as a polygon this wide [m]: an RVO2 obstacle of two
# vertices is a segment only one side of which is tested.
THIN_WALL_WIDTH = 0.002
DISC_SIDES = 16
# RVO2 neighbours: every robot within this distance [m] counts.
PEER_NEIGHBOR_DISTANCE = 10.0
# RVO2's preferred velocities are perturbed by up to this much [m/s], in a random direction,
# as RVO2's own examples do: ORCA deadlocks in a perfectly symmetric encounter.
RVO2_PERTURBATION = 1e-4
# navground agents stop within this fraction of the goal tolerance, so that the run counts them
# as arrived despite its single precision.
PEER_TOLERANCE_FRACTION = 0.5


@dataclasses.dataclass(frozen=True)
class PeerWorld:
    """What a peer is given of a scenario, noise-free: the robots and the static shapes.

    `starts`, `goals` (N, 2) [m], `radii`, `max_speeds` (N,); `dt`, `duration`,
    `goal_tolerance`; `seed`, the scenario's; `polygons`, a list of (V, 2) counter-clockwise
    vertex arrays (walls and polygon obstacles); `disc_centres` (M, 2) and `disc_radii` (M,).
    """

    starts: np.ndarray
    goals: np.ndarray
    radii: np.ndarray
    max_speeds: np.ndarray
    dt: float
    duration: float
    goal_tolerance: float
    seed: int
    polygons: list
    disc_centres: np.ndarray
    disc_radii: np.ndarray


def counter_clockwise(vertices):
    """Return VERTICES (V, 2) in counter-clockwise order (positive signed area)."""
    vertices = np.asarray(vertices, dtype=float)
    x, y = vertices[:, 0], vertices[:, 1]
    area = 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))
    return vertices if area > 0.0 else vertices[::-1].copy()


def wall_rectangle(line, thickness):
    """Return the counter-clockwise rectangle (4, 2) around the wall's capsule [m].

    The wall is the set within half THICKNESS of the segment LINE (2, 2); the rectangle extends
    it by that half-width beyond each end, and is at least THIN_WALL_WIDTH wide.
    """
    start, end = np.asarray(line, dtype=float)
    half = 0.5 * max(thickness, THIN_WALL_WIDTH)
    along = (end - start) / np.linalg.norm(end - start)
    normal = np.array([-along[1], along[0]])
    low, high = start - half * along, end + half * along
    return np.array([low - half * normal, high - half * normal, high + half * normal,
                     low + half * normal])


def disc_polygon(centre, radius, sides=DISC_SIDES):
    """Return the counter-clockwise regular SIDES-gon (SIDES, 2) circumscribed about a disc."""
    angles = 2.0 * math.pi * np.arange(sides) / sides
    reach = radius / math.cos(math.pi / sides)
    return np.asarray(centre, dtype=float) + reach * np.column_stack([np.cos(angles),
                                                                      np.sin(angles)])


def peer_world(scenario):
    """Return the PeerWorld of SCENARIO; ValueError for what the peers cannot be given."""
    world = scenario.static_world
    if world.map_grid is not None:
        raise ValueError(f'scenario {scenario.name!r}: a map file is not given to the peers '
                         '(walls and obstacles only)')
    robots = scenario.robots
    if any(robot.scripted is not None or robot.kinematics != 'holonomic' for robot in robots):
        raise ValueError(f'scenario {scenario.name!r}: the peers run holonomic planned robots '
                         'only')
    polygons = [wall_rectangle(line, thickness) for line, thickness in world.walls]
    polygons += [counter_clockwise(vertices) for vertices in world.polygons]
    return PeerWorld(
        starts=np.array([robot.start for robot in robots]),
        goals=np.array([robot.goal for robot in robots]),
        radii=np.array([robot.radius for robot in robots]),
        max_speeds=np.array([robot.max_speed for robot in robots]),
        dt=scenario.dt, duration=scenario.duration, goal_tolerance=scenario.goal_tolerance,
        seed=scenario.seed, polygons=polygons, disc_centres=world.disc_centres,
        disc_radii=world.disc_radii)


def importable_peers(peers, notes, packages=PEER_PACKAGES):
    """Return those of PEERS whose package imports here; note (and print) each that does not.

    PACKAGES maps a peer to the package it needs.
    """
    found = []
    for peer in peers:
        try:
            importlib.import_module(packages[peer])
        except ImportError:
            notes.append(f'{peer}: {packages[peer]} is not importable here, skipped')
            print(f'note: {notes[-1]}', flush=True)
            continue
        found.append(peer)
    return found


def rvo2_stepper(world):
    """Return step() -> positions (N, 2): one step of RVO2's ORCA on WORLD."""
    import pyrvo

    count = len(world.radii)
    simulator = pyrvo.RVOSimulator()
    simulator.set_time_step(world.dt)
    for start, radius, max_speed in zip(world.starts, world.radii, world.max_speeds,
                                        strict=True):
        simulator.add_agent(tuple(start), PEER_NEIGHBOR_DISTANCE, count, PEER_TIME_HORIZON,
                            DEFAULTS['obstacle_horizon'], float(radius), float(max_speed))
    obstacles = world.polygons + [disc_polygon(centre, radius) for centre, radius in zip(
        world.disc_centres, world.disc_radii, strict=True)]
    for vertices in obstacles:
        simulator.add_obstacle([tuple(vertex) for vertex in vertices])
    simulator.process_obstacles()
    rng = np.random.default_rng(world.seed)

    def step():
        positions = np.array([simulator.get_agent_position(index).to_tuple()
                              for index in range(count)])
        angles = rng.uniform(0.0, 2.0 * math.pi, count)
        preferred = preferred_velocities(positions, world.goals, world.max_speeds,
                                         world.goal_tolerance) + rng.uniform(
            0.0, RVO2_PERTURBATION, count)[:, None] * np.column_stack([np.cos(angles),
                                                                       np.sin(angles)])
        for index in range(count):
            simulator.set_agent_pref_velocity(index, tuple(preferred[index]))
        simulator.do_step()
        return np.array([simulator.get_agent_position(index).to_tuple()
                         for index in range(count)])
    return step


def navground_stepper(world, behavior_type):
    """Return step() -> positions (N, 2): one step of navground's BEHAVIOR_TYPE on WORLD."""
    from navground import core, sim

    simulation = sim.World()
    for vertices in world.polygons:
        for first, second in zip(vertices, np.roll(vertices, -1, axis=0), strict=True):
            simulation.add_wall(sim.Wall(first, second))
    for centre, radius in zip(world.disc_centres, world.disc_radii, strict=True):
        simulation.add_obstacle(sim.Obstacle(centre, float(radius)))
    for start, goal, radius, max_speed in zip(world.starts, world.goals, world.radii,
                                              world.max_speeds, strict=True):
        behavior = core.Behavior.make_type(behavior_type)
        behavior.optimal_speed = float(max_speed)
        if behavior_type == 'ORCA':
            behavior.time_horizon = PEER_TIME_HORIZON
            behavior.static_time_horizon = DEFAULTS['obstacle_horizon']
        task = sim.tasks.WaypointsTask(
            waypoints=[goal], loop=False,
            tolerance=PEER_TOLERANCE_FRACTION * world.goal_tolerance)
        agent = sim.Agent(
            radius=float(radius), behavior=behavior,
            kinematics=core.kinematics.OmnidirectionalKinematics(float(max_speed)), task=task,
            state_estimations=[sim.state_estimations.BoundedStateEstimation(
                range=PEER_NEIGHBOR_DISTANCE)])
        agent.position = start
        simulation.add_agent(agent)

    def step():
        simulation.update(world.dt)
        return np.array([agent.position for agent in simulation.agents], dtype=float)
    return step


def peer_trajectory(peer, world):
    """Run PEER on WORLD to the duration or all robots home; (times, positions, plan_ms).

    `positions` (T, N, 2) from the start; `plan_ms` (T - 1,) each step's time per robot [ms].
    """
    step = (rvo2_stepper(world) if peer == 'rvo2-orca'
            else navground_stepper(world, NAVGROUND_BEHAVIORS[peer]))
    positions, trajectory, plan_ms = world.starts.copy(), [world.starts.copy()], []
    for _ in range(int(round(world.duration / world.dt))):
        if np.all(np.linalg.norm(positions - world.goals, axis=1) <= world.goal_tolerance):
            break
        started = time.perf_counter()
        positions = step()
        plan_ms.append(1e3 * (time.perf_counter() - started) / len(world.radii))
        trajectory.append(positions)
    times = world.dt * np.arange(len(trajectory))
    return times, np.array(trajectory), np.array(plan_ms)


def trajectory_row(scenario, times, positions, plan_ms):
    """Return the measured part of a row: one run of SCENARIO, positions (T, N, 2)."""
    robots = scenario.robots
    names = [robot.name for robot in robots]
    radii = np.array([robot.radius for robot in robots])
    goals = np.array([robot.goal for robot in robots])
    metrics = run_metrics(times, positions, radii, goals, scenario.goal_tolerance, names)
    walls = wall_metrics(positions, radii, names,
                         None if scenario.static_world.empty else scenario.static_world.clearance)
    return {
        'robots': len(robots),
        'arrived': sum(robot['arrived'] for robot in metrics['robots'].values()),
        'makespan_s': metrics['makespan'],
        'min_separation_m': metrics['min_separation'],
        'contacts': metrics['collisions'],
        'min_wall_clearance_m': walls['min_wall_clearance'],
        'wall_contacts': walls['wall_contacts'],
        'plan_ms_per_robot_step': float(np.mean(plan_ms)) if len(plan_ms) else None,
        **trajectory_stalls(times, positions, goals, scenario.goal_tolerance),
    }


def combined(rows):
    """Return one row of runs ROWS of the same world: sums, the worst makespan, the least gaps."""
    def least(key):
        values = [row[key] for row in rows if row[key] is not None]
        return min(values) if values else None
    makespans = [row['makespan_s'] for row in rows]
    return {
        'robots': sum(row['robots'] for row in rows),
        'arrived': sum(row['arrived'] for row in rows),
        'makespan_s': None if None in makespans else max(makespans),
        'min_separation_m': least('min_separation_m'),
        'contacts': sum(row['contacts'] for row in rows),
        'min_wall_clearance_m': least('min_wall_clearance_m'),
        'wall_contacts': sum(row['wall_contacts'] for row in rows),
        'plan_ms_per_robot_step': float(np.mean([row['plan_ms_per_robot_step']
                                                 for row in rows])),
        'stalls': sum(row['stalls'] for row in rows),
        'longest_stall_s': max(row['longest_stall_s'] for row in rows),
        'longest_dwell_s': max(row['longest_dwell_s'] for row in rows),
    }


def noise_free(scenario):
    """Return SCENARIO with every robot's noise zero."""
    quiet = NoiseSpec(0.0, 0.0, 0.0)
    return dataclasses.replace(scenario, robots=tuple(
        dataclasses.replace(robot, noise=quiet) for robot in scenario.robots))


def prvo_trajectory(scenario, method):
    """Run SCENARIO on the in-process engine with METHOD; return (times, positions, plan_ms).

    `times` (T,) [s], `positions` (T, N, 2) [m] after each step, `plan_ms` each robot-step's
    planning time [ms], as `peer_trajectory` gives them.
    """
    _, steps = run_team(scenario, method)
    times = np.array([step.time for step in steps])
    positions = np.array([step.states[:, :2] for step in steps])
    return times, positions, np.concatenate([step.plan_ms for step in steps])


def prvo_row(scenario, method):
    """Run SCENARIO on the in-process engine with METHOD; return its measured row."""
    return trajectory_row(scenario, *prvo_trajectory(scenario, method))


def noise_label(scenario):
    """Return how a row names SCENARIO's noise: 'none' or its standard deviations [m, m/s]."""
    stds = sorted({value for robot in scenario.robots
                   for value in dataclasses.astuple(robot.noise)})
    return 'none' if stds == [0.0] else '/'.join(f'{value:g}' for value in stds)


def labelled(row, scenario_name, planner, noise, seeds):
    """Return ROW with its labels first and its figures rounded for the table."""
    rounding = {'makespan_s': 1, 'min_separation_m': 3, 'min_wall_clearance_m': 3,
                'plan_ms_per_robot_step': 3}
    # Adding 0.0 turns a rounded -0.0 into 0.0.
    figures = {key: (value if value is None or key not in rounding
                     else round(value, rounding[key]) + 0.0) for key, value in row.items()}
    return {'scenario': scenario_name, 'planner': planner, 'noise': noise, 'seeds': seeds,
            **figures, 'arrivals': f'{row["arrived"]}/{row["robots"]}'}


COLUMNS = (('scenario', 'scenario'), ('planner', 'planner'), ('noise', 'noise'),
           ('seeds', 'seeds'), ('arrivals', 'arrived'), ('makespan_s', 'makespan s'),
           ('min_separation_m', 'min robot separation m'), ('contacts', 'robot contacts'),
           ('min_wall_clearance_m', 'min wall clearance m'), ('wall_contacts', 'wall contacts'),
           ('plan_ms_per_robot_step', 'plan ms / robot-step'), *SUMMARY_COLUMNS)


def build_parser():
    """Return the command-line parser of the wall benchmark."""
    parser = argparse.ArgumentParser(
        prog='python -m prvo_sim.bench.walls',
        description='Wall benchmark: prvo (in process) and its peers on the same wall worlds.')
    parser.add_argument('--scenarios', nargs='+', default=list(DEFAULT_SCENARIOS),
                        help='scenario names or files (default: corridor8 doorway8 pillars12)')
    parser.add_argument('--seeds', type=int, default=1,
                        help="noisy prvo runs per method, consecutive seeds from the "
                             "scenario's (default: 1)")
    parser.add_argument('--methods', nargs='*', default=list(METHODS), choices=METHODS,
                        help='prvo planner variants (default: prvo rvo inflate)')
    parser.add_argument('--peers', nargs='*', default=list(PEERS), choices=PEERS,
                        help='peers to run when importable (default: all; none: --peers)')
    parser.add_argument('--planner', nargs='*', default=[], metavar='NAME=VALUE',
                        help="planner parameters of every prvo robot over the scenario's "
                             '(values read as YAML)')
    parser.add_argument('--json', type=pathlib.Path, default=None,
                        help='also write {"runs": [...], "notes": [...]} to this file')
    return parser


def planner_overrides(items):
    """Return {name: checked value} of the NAME=VALUE strings ITEMS; ValueError names a bad one."""
    overrides = {}
    for item in items:
        name, equals, text = item.partition('=')
        if not equals or not name:
            raise ValueError(f'--planner: {item!r} is not NAME=VALUE')
        try:
            overrides[name] = check_parameter(name, yaml.safe_load(text))
        except yaml.YAMLError as error:
            raise ValueError(f'--planner: {name}: {text!r} is not a YAML value') from error
        except ValueError as error:
            raise ValueError(f'--planner: {error}') from None
    return overrides


def with_planner(scenario, overrides):
    """Return SCENARIO with OVERRIDES over every robot's planner parameters."""
    if not overrides:
        return scenario
    return dataclasses.replace(scenario, robots=tuple(
        dataclasses.replace(robot, planner={**robot.planner, **overrides})
        for robot in scenario.robots))


def scenario_rows(path, options, peers):
    """Return every row of the scenario file PATH: prvo's runs, then those of PEERS."""
    overrides = planner_overrides(options.planner)
    scenario = with_planner(load_scenario(path), overrides)
    chosen = ''.join(f' {item}' for item in options.planner)
    rows = []
    for method in options.methods:
        rows.append(labelled(prvo_row(noise_free(scenario), method), scenario.name,
                             f'prvo --method {method}{chosen}', 'none', str(scenario.seed)))
        seeded = [with_planner(load_scenario(path, seed=scenario.seed + offset), overrides)
                  for offset in range(options.seeds)]
        seeds = (str(scenario.seed) if options.seeds == 1
                 else f'{scenario.seed}-{scenario.seed + options.seeds - 1}')
        rows.append(labelled(combined([prvo_row(run, method) for run in seeded]), scenario.name,
                             f'prvo --method {method}{chosen}', noise_label(scenario), seeds))
        print(f'{scenario.name} prvo --method {method}: {rows[-2]["arrivals"]} arrived '
              f'noise-free, {rows[-1]["arrivals"]} with noise', flush=True)
    world = peer_world(scenario) if peers else None
    for peer in peers:
        rows.append(labelled(trajectory_row(scenario, *peer_trajectory(peer, world)),
                             scenario.name, peer, 'none', '-'))
        print(f'{scenario.name} {peer}: {rows[-1]["arrivals"]} arrived', flush=True)
    return rows


def main(argv=None):
    """Run the wall benchmark's command line; return the exit code."""
    options = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    if options.seeds < 1:
        print(f'prvo_sim.bench.walls: error: --seeds: {options.seeds} is not a count (at least 1)',
              file=sys.stderr)
        return 2
    notes = []
    peers = importable_peers(options.peers, notes)
    try:
        planner_overrides(options.planner)
        paths = [find_scenario(name) for name in options.scenarios]
        for path in paths:
            scenario = load_scenario(path)
            if peers:
                peer_world(scenario)
    except ValueError as error:
        # A ScenarioError names the file, the key and the reason.
        print(f'prvo_sim.bench.walls: error: {error}', file=sys.stderr)
        return 2
    rows = []
    try:
        for path in paths:
            rows += scenario_rows(path, options, peers)
    except KeyboardInterrupt:
        print('prvo_sim.bench.walls: interrupted', file=sys.stderr)
        return 130
    report(rows, COLUMNS, notes, options.json)
    checked = [row for row in rows if row['planner'].startswith('prvo --method prvo')]
    return 0 if all(row['arrived'] == row['robots'] for row in checked) else 1


if __name__ == '__main__':
    sys.exit(main())
