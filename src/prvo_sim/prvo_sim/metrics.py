"""Run metrics computed from recorded ground truth: pure functions over numpy arrays.

Shapes: `times` (T,), `positions` (T, N, 2) for N robots sampled at the same T instants, `radii`
(N,), `goals` (N, 2). Definitions follow the metrics.json schema (docs/scenarios.md): a collision
is an entry into contact of a pair of robots, a separation is the centre distance minus the sum of
radii; a wall contact is a robot's entry into contact with a static shape, its wall clearance the
distance from its centre to the nearest shape minus its radius.
"""

import math

import numpy as np

from prvo_sim.static_world import CONTACT_TOLERANCE


def pair_indices(num_robots):
    """Return the index arrays (i, j) of every unordered pair i < j of NUM_ROBOTS robots."""
    return np.triu_indices(num_robots, k=1)


def pairwise_separation(positions, radii):
    """Return the (T, P) separations (distance minus sum of radii) of every pair at every step."""
    positions = np.asarray(positions, dtype=float)
    radii = np.asarray(radii, dtype=float)
    first, second = pair_indices(positions.shape[1])
    distances = np.linalg.norm(positions[:, first, :] - positions[:, second, :], axis=-1)
    return distances - (radii[first] + radii[second])


def min_separation(positions, radii):
    """Return the smallest separation over all pairs and steps (None for a single robot)."""
    separations = pairwise_separation(positions, radii)
    if separations.size == 0:
        return None
    return float(separations.min())


def contact_events(times, positions, radii):
    """Return every entry into contact as (time, i, j, distance), in time order.

    A pair is in contact while its separation is negative; it counts once each time it enters
    contact (including a pair already in contact at the first sample).
    """
    times = np.asarray(times, dtype=float)
    separations = pairwise_separation(positions, radii)
    in_contact = separations < 0.0
    previously = np.vstack([np.zeros((1, in_contact.shape[1]), dtype=bool), in_contact[:-1]])
    steps, pairs = np.nonzero(in_contact & ~previously)
    first, second = pair_indices(np.asarray(positions).shape[1])
    radii = np.asarray(radii, dtype=float)
    events = []
    for step, pair in sorted(zip(steps.tolist(), pairs.tolist(), strict=True)):
        i, j = int(first[pair]), int(second[pair])
        distance = float(separations[step, pair] + radii[i] + radii[j])
        events.append((float(times[step]), i, j, distance))
    return events


def arrival_indices(positions, goals, tolerance):
    """Return, per robot, the first step at which it is within TOLERANCE of its goal.

    None for a robot that never is (it has not arrived). Robots at their goal keep planning
    and may step aside for others: the first arrival is what counts.
    """
    distances = np.linalg.norm(np.asarray(positions, dtype=float) - np.asarray(goals)[None],
                               axis=-1)
    inside = distances <= tolerance
    reached = inside.any(axis=0)
    first = inside.argmax(axis=0)
    return [int(step) if arrived else None for step, arrived in zip(first, reached, strict=True)]


def path_lengths(positions, end_indices=None):
    """Return each robot's travelled distance up to its END_INDICES entry (None: whole run)."""
    positions = np.asarray(positions, dtype=float)
    step_lengths = np.linalg.norm(np.diff(positions, axis=0), axis=-1)
    lengths = []
    for robot in range(positions.shape[1]):
        end = None if end_indices is None else end_indices[robot]
        lengths.append(float(step_lengths[:end, robot].sum()))
    return lengths


def distribution_summary(values):
    """Return {'median', 'p95', 'max'} of VALUES, each None when there are none."""
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return {'median': None, 'p95': None, 'max': None}
    return {'median': float(np.median(values)), 'p95': float(np.percentile(values, 95)),
            'max': float(values.max())}


def run_metrics(times, positions, radii, goals, goal_tolerance, robot_names, scripted=None):
    """Return the ground-truth part of metrics.json for one run.

    Keys: robots (arrived, time_to_goal, path_length, scripted per robot), scripted_robots,
    success_rate, collisions, min_separation, makespan, mean_time_to_goal, sim_time. Times are
    measured from times[0]; a robot's arrival is its first within the tolerance, and its path
    length runs up to it (the whole run if it did not arrive). SCRIPTED (N,) marks the robots
    that follow waypoints (default: none): they count in collisions and min_separation, while
    success_rate, makespan and mean_time_to_goal are over the others; their `arrived` and
    `time_to_goal` are None.
    """
    times = np.asarray(times, dtype=float)
    scripted = (np.zeros(len(robot_names), dtype=bool) if scripted is None
                else np.asarray(scripted, dtype=bool))
    arrivals = [None if is_scripted else arrival for arrival, is_scripted in zip(
        arrival_indices(positions, goals, goal_tolerance), scripted, strict=True)]
    lengths = path_lengths(positions, arrivals)
    robots = {}
    times_to_goal = []
    for name, arrival, length, is_scripted in zip(robot_names, arrivals, lengths, scripted,
                                                  strict=True):
        time_to_goal = None if arrival is None else float(times[arrival] - times[0])
        if time_to_goal is not None:
            times_to_goal.append(time_to_goal)
        robots[name] = {'arrived': None if is_scripted else arrival is not None,
                        'time_to_goal': time_to_goal, 'path_length': length,
                        'scripted': bool(is_scripted)}
    planned_count = int((~scripted).sum())
    all_arrived = len(times_to_goal) == planned_count
    return {
        'robots': robots,
        'scripted_robots': [name for name, is_scripted in zip(robot_names, scripted,
                                                               strict=True) if is_scripted],
        'success_rate': len(times_to_goal) / planned_count if planned_count else None,
        'collisions': len(contact_events(times, positions, radii)),
        'min_separation': min_separation(positions, radii),
        'makespan': max(times_to_goal) if all_arrived and times_to_goal else None,
        'mean_time_to_goal': float(np.mean(times_to_goal)) if times_to_goal else None,
        'sim_time': float(times[-1] - times[0]),
    }


def wall_metrics(positions, radii, robot_names, clearance=None,
                 contact_tolerance=CONTACT_TOLERANCE):
    """Return how close the robots came to the walls, obstacles and map, per robot and overall.

    CLEARANCE maps points (P, 2) to their signed distances to the nearest static shape (P,)
    [m] (`StaticWorld.clearance`); None for a world without any. A robot is in contact while
    its clearance is at most CONTACT_TOLERANCE (the world stops it at the surface) and counts
    once each time it enters contact (including at the first sample). Returns {'robots':
    {name: {'wall_contacts', 'min_wall_clearance'}}, 'wall_contacts': their sum,
    'min_wall_clearance': the least}; clearances are None without static shapes.
    """
    positions = np.asarray(positions, dtype=float)
    if clearance is None or positions.size == 0:
        return {'robots': {name: {'wall_contacts': 0, 'min_wall_clearance': None}
                           for name in robot_names},
                'wall_contacts': 0, 'min_wall_clearance': None}
    steps, robots = positions.shape[:2]
    clearances = (np.asarray(clearance(positions.reshape(-1, 2))).reshape(steps, robots)
                  - np.asarray(radii, dtype=float))
    touching = clearances <= contact_tolerance
    entries = touching & ~np.vstack([np.zeros((1, robots), dtype=bool), touching[:-1]])
    counts = entries.sum(axis=0)
    lowest = clearances.min(axis=0)
    return {'robots': {name: {'wall_contacts': int(count), 'min_wall_clearance': float(least)}
                       for name, count, least in zip(robot_names, counts, lowest, strict=True)},
            'wall_contacts': int(counts.sum()), 'min_wall_clearance': float(lowest.min())}


def plan_quality(tallies):
    """Return how far the robots' plans met the chance constraint, per robot and overall.

    TALLIES maps each planned robot to (plans, infeasible plans, lowest achieved eta). Returns
    {'robots': {name: {'plans', 'infeasible_fraction', 'min_achieved_eta'}},
    'infeasible_fraction': infeasible plans / plans of all robots, 'min_achieved_eta': the
    lowest of all}; a fraction or eta is None where there was no plan.
    """
    robots = {}
    for name, (plans, infeasible, min_achieved_eta) in tallies.items():
        if not 0 <= infeasible <= plans:
            raise ValueError(f'{name}: {infeasible} infeasible plans of {plans}')
        robots[name] = {
            'plans': int(plans),
            'infeasible_fraction': infeasible / plans if plans else None,
            'min_achieved_eta': float(min_achieved_eta) if plans else None}
    plans = sum(plans for plans, _, _ in tallies.values())
    etas = [robot['min_achieved_eta'] for robot in robots.values() if robot['plans']]
    return {'robots': robots,
            'infeasible_fraction': (sum(infeasible for _, infeasible, _ in tallies.values())
                                    / plans if plans else None),
            'min_achieved_eta': min(etas) if etas else None}


def aggregate(metrics_list, keys):
    """Return {key: {'mean', 'std', 'min', 'max', 'n'}} over the runs' numeric values of KEYS.

    A run whose value is None (e.g. no makespan because a robot did not arrive) is left out of
    that key's statistics; 'n' says how many runs contributed. Dotted keys reach into nested
    dictionaries ('planner_ms.median').
    """
    summary = {}
    for key in keys:
        values = []
        for metrics in metrics_list:
            value = metrics
            for part in key.split('.'):
                value = value.get(part) if isinstance(value, dict) else None
            if value is not None and not (isinstance(value, float) and math.isnan(value)):
                values.append(float(value))
        if values:
            array = np.asarray(values)
            summary[key] = {'mean': float(array.mean()), 'std': float(array.std()),
                            'min': float(array.min()), 'max': float(array.max()),
                            'n': len(values)}
        else:
            summary[key] = {'mean': None, 'std': None, 'min': None, 'max': None, 'n': 0}
    return summary
