"""Keep right in a run: opposite files in a corridor pass on their right, as certified as ever.

Two robots each way, in single file on the corridor's centre line, with noise, at the planner's
defaults (certified bound, eta 0.95). Without the rule the side each pair passes on is the
noise's choice; with it every pair passes on its right. Only the preferred velocity leans:
a Monte Carlo check with a sampler of its own finds every encounter plan of the run safe
within its horizon with at least eta.
"""

import math

import numpy as np
import pytest

from prvo_sim.engine import InProcessTeam
from prvo_sim.runner.session import planner_values
from prvo_sim.scenario import load_scenario

CORRIDOR = """name: corridor_files
seed: 1
dt: 0.1
duration: 40.0
goal_tolerance: 0.2
noise:
  position_std: 0.05
  velocity_std: 0.05
  actuation_std: 0.05
walls:
  - line: [[-5.0, 1.25], [5.0, 1.25]]
    thickness: 0.1
  - line: [[-5.0, -1.25], [5.0, -1.25]]
    thickness: 0.1
robots:
  - {name: east_0, start: [-4.0, 0.0], goal: [4.0, 0.0], radius: 0.25, max_speed: 1.0}
  - {name: east_1, start: [-3.0, 0.0], goal: [3.0, 0.0], radius: 0.25, max_speed: 1.0}
  - {name: west_0, start: [4.0, 0.0], goal: [-4.0, 0.0], radius: 0.25, max_speed: 1.0}
  - {name: west_1, start: [3.0, 0.0], goal: [-3.0, 0.0], radius: 0.25, max_speed: 1.0}
"""
EAST, WEST = (0, 1), (2, 3)
SAMPLES = 4000
# Neighbours nearer than this [m] make a plan an encounter's.
ENCOUNTER = 3.0


def run(tmp_path, seed, keep_right, on_step=None):
    """Return (whether all arrived, the y offsets east - west at each pass (list))."""
    path = tmp_path / 'corridor.yaml'
    path.write_text(CORRIDOR)
    scenario = load_scenario(path, seed=seed)
    values = [{**planner_values(robot, scenario, 'prvo', None), 'keep_right': keep_right}
              for robot in scenario.robots]
    team = InProcessTeam(scenario, values, seed=seed)
    previous, offsets = None, []
    while not team.finished:
        positions = np.asarray(team.do_step().states)[:, :2]
        if on_step is not None:
            on_step(team, positions)
        if previous is not None:
            for east in EAST:
                for west in WEST:
                    before = previous[east, 0] - previous[west, 0]
                    if before < 0.0 <= positions[east, 0] - positions[west, 0]:
                        offsets.append(positions[east, 1] - positions[west, 1])
        previous = positions
        if all(command.arrived for command in team.last_commands):
            return True, offsets
    return False, offsets


def test_without_the_rule_the_noise_picks_the_side(tmp_path):
    sides = [np.sign(run(tmp_path, seed, 0.0)[1]) for seed in (1, 2)]
    assert any((side > 0).any() for side in sides)


@pytest.mark.parametrize('seed', [1, 2, 3])
def test_with_the_rule_every_pair_passes_on_its_right(tmp_path, seed):
    arrived, offsets = run(tmp_path, seed, 0.3)
    assert arrived
    # Each of the four east-west pairs passes once, east below west (on each one's right),
    # at least a sum of radii apart sideways.
    assert len(offsets) == 4
    assert max(offsets) <= -0.5


def gaussian(rng, mean, covariance, count):
    """Draw COUNT samples (count, n) of N(MEAN, COVARIANCE) from standard normals."""
    values, vectors = np.linalg.eigh(covariance)
    root = vectors * np.sqrt(np.clip(values, 0.0, None))
    return np.asarray(mean) + rng.standard_normal((count, len(mean))) @ root.T


def safe_share(rng, ego, neighbour, command, config):
    """Return the sampled share of executions safe within the horizon, as the planner states it.

    Relative position r and velocity u sampled from the beliefs and the actuation noise, the
    ego taking the share of the avoidance its neighbour leaves it: u = (executed - v_ego) /
    (1 - s) + v_ego - v_neighbour for a neighbour announcing share s (2 executed - v_ego -
    v_neighbour for a reciprocating one, executed - v_neighbour for one standing at its goal);
    safe: on [0, horizon] the robots come no closer than the sum of radii, or than they
    already are.
    """
    own = gaussian(rng, np.r_[ego.position, ego.velocity], ego.covariance, SAMPLES)
    other = gaussian(rng, np.r_[neighbour.position, neighbour.velocity], neighbour.covariance,
                     SAMPLES)
    executed = command + gaussian(rng, np.zeros(2), config.actuation_cov, SAMPLES)
    r = own[:, :2] - other[:, :2]
    share = neighbour.avoidance_share
    u = (executed - own[:, 2:]) / (1.0 - share) + own[:, 2:] - other[:, 2:]
    closest = np.clip(-np.sum(r * u, axis=1) / np.maximum(np.sum(u * u, axis=1), 1e-300),
                      0.0, config.time_horizon)
    distance_sq = np.sum((r + closest[:, None] * u) ** 2, axis=1)
    radius = ego.radius + neighbour.radius + config.safety_margin
    return np.mean(distance_sq >= np.minimum(radius ** 2, np.sum(r * r, axis=1)) - 1e-12)


def test_every_encounter_plan_with_the_rule_keeps_its_probability(tmp_path):
    rng = np.random.default_rng(38)
    checked = []

    def check(team, positions):
        for request, command in zip(team.last_requests, team.last_commands, strict=True):
            if request.problem is None or not command.result.feasible:
                continue
            ego, neighbours, _, config = request.problem[:4]
            for neighbour in neighbours:
                if np.hypot(*(neighbour.position - ego.position)) > ENCOUNTER:
                    continue
                checked.append((safe_share(rng, ego, neighbour, command.velocity, config),
                                config.effective_eta))

    assert run(tmp_path, 1, 0.3, check)[0]
    shares, etas = np.array(checked).T
    assert len(shares) >= 100
    tolerance = 4.0 * np.sqrt(etas * (1.0 - etas) / SAMPLES)
    assert (shares >= etas - tolerance).all(), (shares - etas).min()
    assert math.isclose(etas.min(), 0.95)
