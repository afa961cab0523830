"""The fallback without a feasible velocity, on noise-free encounters, against plain geometry."""

import math

import numpy as np
import pytest

from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity
from prvo_planner.core.probability import eta_from_k

RADIUS = 0.3
HORIZON = 5.0
MAX_SPEED = 1.0
# The core's default control period.
PERIOD = 0.1


def trapped_encounter(rng):
    """
    Ego at the origin, one neighbour touching it, the others closing in from a ring.

    Exactly known beliefs (zero covariance). The touching neighbour drifts slowly, so that
    moving straight away from it recedes; the ring is dense enough that nothing is feasible.
    """
    ego = AgentBelief([0.0, 0.0], rng.uniform(-0.3, 0.3, size=2), np.zeros((4, 4)), RADIUS)
    bearing = rng.uniform(0.0, 2.0 * math.pi)
    toward = np.array([math.cos(bearing), math.sin(bearing)])
    neighbours = [AgentBelief(rng.uniform(0.45, 0.58) * toward, rng.uniform(-0.1, 0.1, size=2),
                              np.zeros((4, 4)), RADIUS)]
    count = int(rng.integers(5, 9))
    for index in range(count):
        angle = bearing + 2.0 * math.pi * (index + rng.uniform(0.3, 0.7)) / count
        direction = np.array([math.cos(angle), math.sin(angle)])
        neighbours.append(AgentBelief(rng.uniform(0.75, 1.3) * direction,
                                      -rng.uniform(0.2, 0.8) * direction, np.zeros((4, 4)),
                                      RADIUS))
    return ego, neighbours, -toward * rng.uniform(0.5, 1.0)


def relative_motion(ego, neighbour, velocity):
    """Mean relative position and reciprocal relative velocity at command VELOCITY (..., 2)."""
    offset = ego.position - neighbour.position
    return offset, 2.0 * np.asarray(velocity) - ego.velocity - neighbour.velocity


def closest_approach_time_to_collision(offset, relative, radius):
    """Time the line ``offset + t relative`` first comes within RADIUS, from its closest point."""
    speed_sq = np.sum(relative * relative, axis=-1)
    with np.errstate(divide='ignore', invalid='ignore'):
        closest_time = -(relative @ offset) / speed_sq
        miss_sq = offset @ offset - closest_time ** 2 * speed_sq
        entry = closest_time - np.sqrt(np.maximum(radius ** 2 - miss_sq, 0.0) / speed_sq)
    hits = (closest_time > 0.0) & (miss_sq <= radius ** 2)
    return np.where(hits, np.maximum(entry, 0.0), np.inf)


def measures(ego, neighbours, velocities):
    """
    (contact entered within a period, closing on near neighbours, time to collision) per command.

    The first is how far the command moves into contact (or deeper into an overlap) within one
    control period: the closest point of the segment the relative position sweeps; a neighbour
    is near when some command could close its gap within the period (relative speed at most
    ``2 v_max + |v_i + v_j|``).
    """
    intrusion = np.zeros(velocities.shape[:-1])
    closing = np.zeros(velocities.shape[:-1])
    collision = np.full(velocities.shape[:-1], HORIZON)
    for neighbour in neighbours:
        offset, relative = relative_motion(ego, neighbour, velocities)
        radius = ego.radius + neighbour.radius
        distance = math.hypot(*offset)
        end = offset + PERIOD * relative
        # The segment from OFFSET to END: its point nearest the origin.
        step = end - offset
        with np.errstate(divide='ignore', invalid='ignore'):
            share = np.clip(-(step @ offset) / np.sum(step * step, axis=-1), 0.0, 1.0)
        share = np.nan_to_num(share)
        closest = np.linalg.norm(offset + share[..., None] * step, axis=-1)
        intrusion = np.maximum(intrusion, min(distance, radius) - closest)
        fastest = 2.0 * MAX_SPEED + math.hypot(*(ego.velocity + neighbour.velocity))
        if distance < radius + fastest * PERIOD:
            # The distance a short while later: shrinking means closing in.
            later = np.linalg.norm(offset + 1e-6 * relative, axis=-1)
            closing = np.maximum(closing, np.maximum(distance - later, 0.0) / 1e-6)
        if distance >= radius:
            collision = np.minimum(collision,
                                   closest_approach_time_to_collision(offset, relative, radius))
    return intrusion, closing, collision


def fine_grid():
    """Commands on 721 headings x 101 speeds up to MAX_SPEED, shape (K, 2)."""
    headings = np.linspace(0.0, 2.0 * math.pi, 721)
    speeds = np.linspace(0.0, MAX_SPEED, 101)
    grid = speeds[:, None, None] * np.stack([np.cos(headings), np.sin(headings)], axis=1)
    return grid.reshape(-1, 2)


@pytest.mark.parametrize('model', ['rvo', 'prvo'])
def test_noise_free_fallback_recedes_from_contact_and_keeps_collisions_furthest(model):
    rng = np.random.default_rng(140)
    config = PlannerConfig(model=model, max_speed=MAX_SPEED, time_horizon=HORIZON,
                           num_directions=64, inertia=0.5, passing_bias=0.1)
    grid = fine_grid()
    checked = 0
    for _ in range(40):
        ego, neighbours, v_pref = trapped_encounter(rng)
        result = plan_velocity(ego, neighbours, v_pref, config, previous=v_pref)
        if result.candidates_feasible:
            continue
        assert not result.feasible
        assert result.eta_bound == eta_from_k(max(result.achieved_k, 0.0))
        intrusion, closing, collision = measures(ego, neighbours, result.velocity)
        grid_intrusion, grid_closing, grid_collision = measures(ego, neighbours, grid)
        # Some command enters no contact and recedes from every near neighbour (the touching
        # one among them): so does the chosen one.
        safe = (grid_intrusion <= 1e-9) & (grid_closing <= 1e-9)
        if not safe.any():
            continue
        assert intrusion <= 1e-6
        assert closing <= 1e-6
        # Among those commands, no other on a fine grid delays the first collision by much
        # more than the candidates' spacing allows (1/8 of v_max in speed, 1/64 turn).
        best = grid_collision[safe].max()
        assert collision >= 0.8 * best - 0.05, (collision, best)
        checked += 1
    assert checked >= 10


def test_chosen_fallback_is_the_best_candidate_by_its_measure():
    # The candidates are v_pref's direction, the current velocity's and 64 headings, at the
    # direction's preferred speed and 9 speeds from 0 to v_max: the chosen one is best among
    # them, lexicographically by the contact it enters within the period, its closing on near
    # neighbours and its time to collision.
    rng = np.random.default_rng(141)
    config = PlannerConfig(model='rvo', max_speed=MAX_SPEED, time_horizon=HORIZON,
                           num_directions=64)
    headings = 2.0 * math.pi * np.arange(64) / 64
    checked = 0
    for _ in range(40):
        ego, neighbours, v_pref = trapped_encounter(rng)
        result = plan_velocity(ego, neighbours, v_pref, config)
        if result.candidates_feasible:
            continue
        checked += 1
        directions = [np.stack([np.cos(headings), np.sin(headings)], axis=1)]
        for vector in (ego.velocity, v_pref):
            directions.append(vector[None, :] / np.linalg.norm(vector))
        directions = np.concatenate(directions)
        preferred = np.clip(directions @ v_pref / MAX_SPEED, 0.0, 1.0)
        speeds = np.concatenate([np.broadcast_to(np.linspace(0.0, 1.0, 9), (len(directions), 9)),
                                 preferred[:, None]], axis=1)
        candidates = (MAX_SPEED * speeds[..., None] * directions[:, None, :]).reshape(-1, 2)
        intrusion, closing, collision = measures(ego, neighbours, candidates)
        chosen_intrusion, chosen_closing, chosen_collision = measures(ego, neighbours,
                                                                      result.velocity)
        assert chosen_intrusion <= intrusion.min() + 1e-6
        ranked = intrusion <= intrusion.min() + 1e-6
        assert chosen_closing <= closing[ranked].min() + 1e-6
        ranked &= closing <= closing[ranked].min() + 1e-6
        assert chosen_collision >= collision[ranked].max() - 1e-6
    assert checked >= 10
