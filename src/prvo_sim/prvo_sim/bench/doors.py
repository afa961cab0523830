"""Doors benchmark: one robot alone at a door it fits through, three position stds to spare.

    python -m prvo_sim.bench.doors [--radii 0.2 0.25 0.3] [--stds 0.02 0.05]
                                   [--etas 0.95 0.99] [--angles 0 45] [--seeds 10]
                                   [--json PATH]

Each case is a wall along x = 0 (THICKNESS thick, 2 WALL_HALF long) with a door centred at the
origin whose clear width (between the jambs' surfaces) is ``2 r + 6 sigma_p``; one robot of
radius r, noise sigma_p on position, velocity and actuation, the planner's defaults but
``eta``. It starts APPROACH from the door's centre at the angle [deg] from the wall's normal
and heads for the point opposite. Every case runs on the in-process engine for DURATION per
seed (consecutive seeds from 1). Per case: the robots through (centre past the wall's far face
by its radius), the wall contacts, the least clearance of a robot from the real walls (the
simulator's, minus the radius) and the median time through.

Exit codes: 0 every robot through without a contact, 1 one was not, 2 bad input.
"""

import argparse
import json
import math
import pathlib
import sys
import tempfile

import numpy as np

from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import load_scenario

THICKNESS = 0.1
WALL_HALF = 4.0
APPROACH = 3.0
DURATION = 30.0


def door_scenario(radius, clear_width, noise, angle=0.0, eta=None):
    """Return the YAML text of one robot at a door of CLEAR_WIDTH [m]; ANGLE [rad].

    The jambs are walls along x = 0 whose rounded tips are the door's edges.
    """
    tip = 0.5 * clear_width + 0.5 * THICKNESS
    heading = np.array([math.cos(angle), math.sin(angle)])
    start, goal = -APPROACH * heading, APPROACH * heading
    planner = '' if eta is None else f'planner:\n  eta: {eta}\n'
    return f"""name: door
description: One robot, one door of clear width {clear_width:.3f} m.
seed: 1
dt: 0.1
duration: {DURATION}
goal_tolerance: 0.2
noise:
  position_std: {noise}
  velocity_std: {noise}
  actuation_std: {noise}
{planner}walls:
  - line: [[0.0, {WALL_HALF}], [0.0, {tip}]]
    thickness: {THICKNESS}
  - line: [[0.0, {-WALL_HALF}], [0.0, {-tip}]]
    thickness: {THICKNESS}
robots:
  - name: robot_0
    start: [{start[0]:.6f}, {start[1]:.6f}]
    goal: [{goal[0]:.6f}, {goal[1]:.6f}]
    radius: {radius}
    max_speed: 1.0
"""


def run_door(path, seed):
    """Run the scenario file PATH once in process: (time through or None, contacts, clearance).

    The clearance is the least of the robot's [m]. Through: the ground-truth centre past the
    wall's far face by the radius; the run stops there.
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
        if step.states[0, 0] > 0.5 * THICKNESS + radius:
            return step.time, contacts, clearance
    return None, contacts, clearance


def run_case(folder, radius, sigma, eta, angle_deg, seeds):
    """Run one case over SEEDS; return its row (a dict)."""
    width = 2.0 * radius + 6.0 * sigma
    path = pathlib.Path(folder) / f'door_{radius}_{sigma}_{eta}_{angle_deg}.yaml'
    path.write_text(door_scenario(radius, width, sigma, math.radians(angle_deg), eta))
    runs = [run_door(path, seed) for seed in seeds]
    times = [through for through, _, _ in runs if through is not None]
    return {'radius': radius, 'sigma_p': sigma, 'eta': eta, 'angle_deg': angle_deg,
            'clear_width': width, 'seeds': len(runs), 'through': len(times),
            'contacts': sum(contacts for _, contacts, _ in runs),
            'min_clearance': min(clearance for _, _, clearance in runs),
            'median_time': float(np.median(times)) if times else None}


def _row(row):
    time_through = 'n/a' if row['median_time'] is None else f"{row['median_time']:.1f}"
    return (f"| {row['radius']:.2f} | {row['sigma_p']:.2f} | {row['clear_width']:.2f} "
            f"| {row['eta']:.2f} | {row['angle_deg']:g} | {row['through']}/{row['seeds']} "
            f"| {row['contacts']} | {row['min_clearance']:.3f} | {time_through} |")


def main(argv=None):
    """Run the sweep; print its table (Markdown); return the exit code."""
    parser = argparse.ArgumentParser(prog='python -m prvo_sim.bench.doors',
                                     description=__doc__.split('\n')[0])
    parser.add_argument('--radii', type=float, nargs='+', default=[0.2, 0.25, 0.3])
    parser.add_argument('--stds', type=float, nargs='+', default=[0.02, 0.05])
    parser.add_argument('--etas', type=float, nargs='+', default=[0.95, 0.99])
    parser.add_argument('--angles', type=float, nargs='+', default=[0.0, 45.0])
    parser.add_argument('--seeds', type=int, default=10)
    parser.add_argument('--json', type=pathlib.Path, default=None)
    try:
        options = parser.parse_args(argv)
    except SystemExit as exit_:
        return 2 if exit_.code else 0
    if options.seeds < 1:
        print('--seeds must be at least 1', file=sys.stderr)
        return 2
    print('| r [m] | sigma_p [m] | door [m] | eta | angle [deg] | through | contacts '
          '| least clearance [m] | median time through [s] |')
    print('|---|---|---|---|---|---|---|---|---|')
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for radius in options.radii:
            for sigma in options.stds:
                for eta in options.etas:
                    for angle in options.angles:
                        rows.append(run_case(folder, radius, sigma, eta, angle,
                                             range(1, options.seeds + 1)))
                        print(_row(rows[-1]), flush=True)
    if options.json is not None:
        options.json.write_text(json.dumps(rows, indent=2))
    return 0 if all(row['through'] == row['seeds'] and row['contacts'] == 0
                    for row in rows) else 1


if __name__ == '__main__':
    sys.exit(main())
