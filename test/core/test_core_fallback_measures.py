"""The fallback's compiled measures against sampled paths and closed forms in mpmath."""

import math

import mpmath
import numpy as np

from prvo_planner.core.choice import fallback_measures

PERIOD = 0.1
HORIZON = 5.0
# Samples of t over one period: the sampled closest distance is within |u| PERIOD / SAMPLES of
# the true one.
SAMPLES = 4000


def random_case(rng, count, candidates):
    """Return (velocities, origin, lead, radius): some neighbours touching, some standing."""
    velocities = rng.uniform(-1.0, 1.0, (candidates, 2))
    velocities[0] = 0.0
    bearing = rng.uniform(0.0, 2.0 * math.pi, count)
    distance = rng.uniform(0.2, 2.5, count)
    position = distance[:, None] * np.stack([np.cos(bearing), np.sin(bearing)], axis=1)
    drift = rng.uniform(-1.0, 1.0, (count, 2))
    if count:
        drift[0] = 0.0
    lead = rng.choice([0.5, 1.0], count) * rng.uniform(0.8, 1.0, count)
    radius = rng.uniform(0.4, 0.9, count)
    return velocities, np.hstack([position, drift]), lead, radius


def sampled_closest(position, relative):
    """Return the smallest |r + t u| over SAMPLES + 1 evenly spaced t in [0, PERIOD]."""
    times = np.linspace(0.0, PERIOD, SAMPLES + 1)
    return float(np.min(np.hypot(position[0] + times * relative[0],
                                 position[1] + times * relative[1])))


def first_contact(position, relative, radius):
    """First t >= 0 with |r + t u| = R, by the textbook root in 50 digits (inf: never)."""
    mpmath.mp.dps = 50
    r_x, r_y = mpmath.mpf(position[0]), mpmath.mpf(position[1])
    u_x, u_y = mpmath.mpf(relative[0]), mpmath.mpf(relative[1])
    a = u_x * u_x + u_y * u_y
    half_b = r_x * u_x + r_y * u_y
    c = r_x * r_x + r_y * r_y - mpmath.mpf(radius) ** 2
    if a == 0 or half_b * half_b - a * c < 0:
        return math.inf
    roots = [(-half_b - mpmath.sqrt(half_b * half_b - a * c)) / a,
             (-half_b + mpmath.sqrt(half_b * half_b - a * c)) / a]
    ahead = [root for root in roots if root >= 0]
    return float(min(ahead)) if ahead else math.inf


def oracle(velocities, origin, lead, radius):
    """Return the four measures of each candidate, neighbour by neighbour, by definition."""
    fastest = max(math.hypot(*velocity) for velocity in velocities)
    result = []
    for velocity in velocities:
        intrusion, closing, collision, passes = 0.0, 0.0, math.inf, 0
        for row, share, size in zip(origin, lead, radius, strict=True):
            position = row[:2]
            relative = share * velocity + row[2:]
            distance = math.hypot(*position)
            intrusion = max(intrusion, min(distance, size) - sampled_closest(position, relative))
            # The radial speed by angles: |u| cos of the angle between u and r.
            speed = math.hypot(*relative)
            angle = math.atan2(relative[1], relative[0]) - math.atan2(position[1], position[0])
            radial = speed * math.cos(angle)
            reach = PERIOD * (share * fastest + math.hypot(*row[2:]))
            if distance < size + reach:
                closing = max(closing, -radial)
            if distance >= size:
                collision = min(collision, first_contact(position, relative, size))
            # Approaching, and r x u < 0: u turns clockwise from r.
            if speed > 0.0 and radial < 0.0 and math.sin(angle) < 0.0:
                passes += 1
        result.append((intrusion, closing, min(collision, HORIZON), passes))
    return [np.array(column) for column in zip(*result, strict=True)]


def test_the_fallback_measures_match_sampled_paths_and_closed_forms():
    rng = np.random.default_rng(40)
    seen = np.zeros(4, dtype=bool)
    for count in (1, 3, 8, 15):
        velocities, origin, lead, radius = random_case(rng, count, 60)
        intrusion, closing, collision, passes = fallback_measures(velocities, origin, lead,
                                                                  radius, HORIZON, PERIOD)
        expected = oracle(velocities, origin, lead, radius)
        # Sampling overestimates the closest distance by at most |u| PERIOD / SAMPLES.
        sampling = 3.0 * PERIOD / SAMPLES
        assert np.all(intrusion >= expected[0] - 1e-12)
        assert np.all(intrusion <= expected[0] + sampling)
        assert np.allclose(closing, expected[1], rtol=1e-12, atol=1e-12)
        assert np.allclose(collision, expected[2], rtol=1e-9, atol=1e-12)
        assert passes.dtype == np.int64
        assert np.array_equal(passes, expected[3])
        seen |= [np.any(intrusion > 0.0), np.any(closing > 0.0),
                 np.any(collision < HORIZON), np.any(passes > 0)]
    assert np.all(seen)


def test_a_head_on_path_intrudes_fully_and_collides_on_time():
    # A neighbour 1 m ahead closing at 2 m/s with R = 0.95: contact after 0.025 s; the path
    # sweeps through the centre-line to 0.8 m, so it goes 0.15 m into contact.
    velocities = np.array([[1.0, 0.0], [0.0, 0.0], [-1.0, 0.0]])
    origin = np.array([[-1.0, 0.0, 1.0, 0.0]])
    intrusion, closing, collision, passes = fallback_measures(
        velocities, origin, np.array([1.0]), np.array([0.95]), HORIZON, PERIOD)
    assert np.allclose(intrusion, [0.15, 0.05, 0.0], atol=1e-15)
    assert np.allclose(closing, [2.0, 1.0, 0.0], atol=1e-15)
    assert np.allclose(collision, [0.025, 0.05, HORIZON], atol=1e-15)
    assert np.array_equal(passes, [0, 0, 0])


def test_without_neighbours_and_while_touching():
    velocities = np.array([[0.5, 0.0], [0.0, -0.5]])
    empty = fallback_measures(velocities, np.zeros((0, 4)), np.zeros(0), np.zeros(0), math.inf,
                              PERIOD)
    assert [list(measure) for measure in empty] == [[0.0, 0.0], [0.0, 0.0],
                                                     [math.inf, math.inf], [0, 0]]
    # Touching (0.5 < R = 0.6): no time to collision, and moving closer adds to the overlap.
    origin = np.array([[0.5, 0.0, 0.0, 0.0]])
    intrusion, _, collision, _ = fallback_measures(
        np.array([[1.0, 0.0], [-1.0, 0.0]]), origin, np.array([1.0]), np.array([0.6]), HORIZON,
        PERIOD)
    assert np.allclose(intrusion, [0.0, 0.1], atol=1e-15)
    assert np.array_equal(collision, [HORIZON, HORIZON])
