"""
Measurements of the certified bound on ``P(f >= 0)`` (docs/method.md, section 13).

Usage: ``python -m prvo_planner.certificate_bench [--encounters 150] [--seed 1] [--json PATH]``.

Seeded random two-robot encounters (``encounters.py``: the neighbour 1.5-5 m away, shares 0 and
1/2 alternating, actuation noise up to 0.1 m/s) with two kinds of beliefs: ``tracked``, the
covariances a constant-velocity tracker (``estimation.py``) reaches from anisotropic odometry and
predicts up to 0.3 s ahead, and ``generic``, every component correlated with every other
(``encounters.random_covariance``). Along a ray of commands towards the neighbour it reports:

* at Cantelli's edges ``k = 1, 2, 3`` (the planner's choice when the constraint binds): the
  certified bound, the sampled probability (100 000 samples) and their gap as wedges are added;
* the median ``k = E[f] / sd[f]`` at the certified edge, where the bound first reaches ``eta`` for
  ``eta = 0.8, 0.9, 0.95, 0.99``, against Cantelli's ``sqrt(eta / (1 - eta))``;
* the CPU time of one certificate and of 64 in one call.
"""

import argparse
import json
import math
import time

import numpy as np

from prvo_planner.core import AgentBelief, PlannerConfig, rvo_moments
from prvo_planner.core.certificate import rvo_certificate
from prvo_planner.core.encounter import build_encounter
from prvo_planner.core.probability import rvo_satisfaction_probability
from prvo_planner.encounters import EncounterDistribution, random_encounter
from prvo_planner.estimation import ConstantVelocityTracker

ETAS = (0.8, 0.9, 0.95, 0.99)
EDGE_MARGINS = (1.0, 2.0, 3.0)
WEDGES = (16, 32, 64, 128, 256)
SPEEDS = np.linspace(0.0, 1.2, 241)
DISTRIBUTION = EncounterDistribution(
    neighbours=(1, 1), distance=(1.5, 5.0), bearing=(-0.5, 0.5), approach_speed=(0.3, 1.0),
    velocity_scatter=0.2, ego_velocity=(-0.3, 0.8), position_std=(0.03, 0.12),
    velocity_std=(0.03, 0.12))


def tracked_covariance(rng):
    """Return a tracker's covariance after 2 s of odometry at 10 Hz, predicted 0-0.3 s ahead."""
    heading = rng.uniform(-math.pi, math.pi)
    turn = np.array([[math.cos(heading), -math.sin(heading)],
                     [math.sin(heading), math.cos(heading)]])
    # Odometry covariance: each std drawn per axis of the robot's frame, turned to the world.
    measured = np.zeros((4, 4))
    measured[:2, :2] = turn @ np.diag(rng.uniform(0.03, 0.12, size=2) ** 2) @ turn.T
    measured[2:, 2:] = turn @ np.diag(rng.uniform(0.03, 0.12, size=2) ** 2) @ turn.T
    tracker = ConstantVelocityTracker(acceleration_std=rng.uniform(0.2, 1.0))
    for step in range(21):
        tracker.update(0.1 * step, np.zeros(2), np.zeros(2), measured)
    return tracker.belief_at(2.0 + rng.uniform(0.0, 0.3)).covariance


def draw_encounter(rng, index, beliefs):
    """Return (ego, neighbour, actuation covariance) of encounter INDEX."""
    ego, (neighbour,) = random_encounter(rng, DISTRIBUTION)
    share = 0.5 * (index % 2)
    if beliefs == 'tracked':
        ego = AgentBelief(ego.position, ego.velocity, tracked_covariance(rng), ego.radius)
        covariance = tracked_covariance(rng)
    else:
        covariance = neighbour.covariance
    neighbour = AgentBelief(neighbour.position, neighbour.velocity, covariance,
                            neighbour.radius, avoidance_share=share)
    return ego, neighbour, np.diag(rng.uniform(0.0, 0.1, size=2) ** 2)


def collision_ray(ego, neighbour, actuation, rng):
    """Return a ray of commands crossing a collision course (``w`` aims at the neighbour)."""
    encounter = build_encounter(ego, [neighbour], PlannerConfig(actuation_cov=actuation))
    relative = encounter.origin[0]
    # The command with the mean w = -r |w_target| lies on the ray; the ray's direction is turned
    # from it by up to 20 degrees, so that the edges lie at different distances from it.
    target = -relative[:2] / np.hypot(*relative[:2]) * rng.uniform(0.6, 1.6)
    command = (target - relative[2:]) / encounter.lead[0]
    heading = math.atan2(command[1], command[0]) + rng.uniform(-0.35, 0.35)
    return np.array([math.cos(heading), math.sin(heading)])


def ray_gaussians(ego, neighbour, actuation, direction):
    """Relative Gaussians of the commands ``s direction`` for ``s`` in SPEEDS, and ``R``."""
    encounter = build_encounter(ego, [neighbour], PlannerConfig(actuation_cov=actuation))
    means = np.repeat(encounter.origin, SPEEDS.size, axis=0)
    means[:, 2:] += encounter.lead[0] * SPEEDS[:, None] * direction
    return means, encounter.cov[0], float(encounter.combined_radius[0])


def first_at_least(values, threshold, start):
    """Index of the first entry from START on with VALUES >= THRESHOLD, or None."""
    hits = np.flatnonzero(values[start:] >= threshold)
    return None if hits.size == 0 else start + int(hits[0])


def measure(encounters, seed, beliefs):
    """Tightness at Cantelli's edges and the margins at the certified edges, for one kind."""
    rng = np.random.default_rng(seed)
    edges = {k: [] for k in EDGE_MARGINS}
    margins = {eta: [] for eta in ETAS}
    for index in range(encounters):
        ego, neighbour, actuation = draw_encounter(rng, index, beliefs)
        direction = collision_ray(ego, neighbour, actuation, rng)
        means, cov, radius = ray_gaussians(ego, neighbour, actuation, direction)
        expectation, variance = rvo_moments(means, cov, radius)
        k = expectation / np.sqrt(variance)
        # From the most dangerous speed on, the margin rises: the edges lie beyond it.
        start = int(np.argmin(k))
        certified = rvo_certificate(means, cov, radius).probability
        for eta in ETAS:
            at = first_at_least(certified, eta, start)
            if at is not None and at > start:
                # k where the bound crosses eta, between the grid points around it.
                share = (eta - certified[at - 1]) / (certified[at] - certified[at - 1])
                margins[eta].append(float(k[at - 1] + share * (k[at] - k[at - 1])))
        for margin in EDGE_MARGINS:
            at = first_at_least(k, margin, start)
            if at is None or at == start:
                continue
            bounds = [float(rvo_certificate(means[at], cov, radius, wedges=wedges).probability)
                      for wedges in WEDGES]
            sampled = rvo_satisfaction_probability(ego, neighbour, SPEEDS[at] * direction,
                                                   actuation, n_samples=100_000, rng=rng)
            edges[margin].append((sampled, *bounds))
    return edges, margins


def time_certificates(repeats=30):
    """CPU milliseconds (median) of certificates of 1 and 64 pairs, at 64 and 128 wedges."""
    rng = np.random.default_rng(5)
    gaussians = []
    for index in range(64):
        ego, neighbour, actuation = draw_encounter(rng, index, 'tracked')
        means, cov, radius = ray_gaussians(ego, neighbour, actuation, np.array([1.0, 0.0]))
        gaussians.append((means[120], cov, radius))
    means = np.array([mean for mean, _, _ in gaussians])
    covs = np.array([cov for _, cov, _ in gaussians])
    radii = np.array([radius for _, _, radius in gaussians])
    rows = {}
    for wedges in (64, 128):
        for count in (1, 64):
            rvo_certificate(means[:count], covs[:count], radii[:count], wedges=wedges)
            times = []
            for _ in range(repeats):
                start = time.process_time()
                rvo_certificate(means[:count], covs[:count], radii[:count], wedges=wedges)
                times.append(1e3 * (time.process_time() - start))
            rows[f'{count} pair(s), {wedges} wedges'] = float(np.median(times))
    return rows


def main(argv=None):
    """Run the measurements and print them (and write them to --json)."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[1])
    parser.add_argument('--encounters', type=int, default=150)
    parser.add_argument('--seed', type=int, default=1)
    parser.add_argument('--json', default=None)
    args = parser.parse_args(argv)
    report = {}
    for beliefs in ('tracked', 'generic'):
        edges, margins = measure(args.encounters, args.seed, beliefs)
        print(f'{beliefs} beliefs, {args.encounters} encounters')
        kind = report.setdefault(beliefs, {'edges': {}, 'certified_edge_k': {}})
        for margin, rows in edges.items():
            rows = np.array(rows)
            gaps = rows[:, :1] - rows[:, 1:]
            cantelli = margin ** 2 / (1.0 + margin ** 2)
            print(f'  Cantelli edge k = {margin:g} (Cantelli {cantelli:.3f}), {len(rows)} points: '
                  f'sampled median {np.median(rows[:, 0]):.4f}, certified median '
                  f'{np.median(rows[:, 3]):.4f} at 64 wedges')
            for column, wedges in enumerate(WEDGES):
                print(f'    {wedges:4d} wedges: gap median {np.median(gaps[:, column]):.4f}, '
                      f'90th percentile {np.percentile(gaps[:, column], 90):.4f}, max '
                      f'{np.max(gaps[:, column]):.4f}')
            kind['edges'][str(margin)] = {
                'points': len(rows), 'sampled_median': float(np.median(rows[:, 0])),
                'gap_median': dict(zip(map(str, WEDGES), np.median(gaps, axis=0).tolist(),
                                       strict=True)),
                'gap_p90': dict(zip(map(str, WEDGES), np.percentile(gaps, 90, axis=0).tolist(),
                                    strict=True))}
        for eta, values in margins.items():
            print(f'  eta {eta}: median k at the certified edge {np.median(values):.2f} '
                  f'({len(values)} rays; Cantelli {math.sqrt(eta / (1.0 - eta)):.2f})')
            kind['certified_edge_k'][str(eta)] = float(np.median(values))
    report['cpu_ms'] = time_certificates()
    for name, value in report['cpu_ms'].items():
        print(f'  {name}: {value:.2f} ms CPU')
    if args.json:
        with open(args.json, 'w', encoding='utf-8') as stream:
            json.dump(report, stream, indent=2)


if __name__ == '__main__':
    main()
