"""The certified bound on ``P(f >= 0)`` (docs/method.md, section 13) against sampled beliefs.

The oracle is a sampler of this module: each belief and the actuation noise are drawn from
standard normals through their own square roots, ``r`` and ``w`` are formed from the samples by
their definitions (docs/method.md, section 11) and ``f``, ``g`` are evaluated on them. The
relative Gaussian handed to the certificate is the linear map of the independent variables.
"""

import math

import mpmath
import numpy as np
import pytest

from prvo_planner.core import rvo_moments
from prvo_planner.core.certificate import (
    MAX_WEDGES,
    METHODS,
    SLACK,
    condition_bound,
    condition_bound_until_short,
    horizon_certificate,
    receding_certificate,
    rvo_certificate,
)
from prvo_planner.core.certificate_kernels import cut_wedges, harmonic_range
from prvo_planner.core.special import ndtr
from prvo_planner.core.special_kernels import ndtr as compiled_ndtr

# One-sided z for the validity checks; the bound sits below the truth, so a false alarm needs
# a deviation beyond 4.5 standard errors of the sampled probability.
Z = 4.5
# Belief covariances: a tracking filter's (per axis of a frame of its own), isotropic blocks, or
# generic (every component correlated with every other); and geometries: passing at 1.5-5 m,
# near contact, far, or slow relative motion (a broad direction of w).
KINDS = ('filter', 'isotropic', 'generic', 'near', 'far', 'slow')


def square_root(covariance):
    """Return ``L`` with ``L L' = covariance`` for a PSD matrix (zero allowed)."""
    values, vectors = np.linalg.eigh(covariance)
    return vectors * np.sqrt(np.clip(values, 0.0, None))


def belief_covariance(rng, kind):
    """Return a 4 x 4 covariance over ``[x, y, vx, vy]`` of the given kind (see ``KINDS``)."""
    position_std, velocity_std = rng.uniform(0.02, 0.2), rng.uniform(0.02, 0.2)
    if kind == 'isotropic':
        correlation = rng.uniform(-0.8, 0.8)
        blocks = np.array([[position_std ** 2, correlation * position_std * velocity_std],
                           [correlation * position_std * velocity_std, velocity_std ** 2]])
        return np.kron(blocks, np.eye(2))
    if kind in ('filter', 'slow'):
        # A constant-velocity filter: position and velocity correlated along each axis of the
        # robot's frame, the axes a little different.
        positions = position_std ** 2 * rng.uniform(0.7, 1.3, size=2)
        velocities = velocity_std ** 2 * rng.uniform(0.7, 1.3, size=2)
        crosses = rng.uniform(0.3, 0.8, size=2) * np.sqrt(positions * velocities)
        heading = rng.uniform(-math.pi, math.pi)
        turn = np.array([[math.cos(heading), -math.sin(heading)],
                         [math.sin(heading), math.cos(heading)]])
        return np.block([[turn @ np.diag(block) @ turn.T for block in row]
                         for row in ((positions, crosses), (crosses, velocities))])
    scales = np.array([position_std, position_std, velocity_std, velocity_std])
    scales *= rng.uniform(0.5, 1.5, size=4)
    factor = np.eye(4) + 0.5 * rng.normal(size=(4, 4))
    return scales[:, None] * (factor @ factor.T) * scales[None, :] / 2.0


def random_case(rng, kind, share):
    """One encounter: beliefs, actuation noise, share, radius and command."""
    radius = rng.uniform(0.4, 1.0)
    distance = {'near': rng.uniform(radius + 0.02, radius + 0.4),
                'far': rng.uniform(6.0, 12.0)}.get(kind, rng.uniform(1.5, 5.0))
    bearing = rng.uniform(-math.pi, math.pi)
    ego = {'position': rng.normal(size=2), 'velocity': rng.uniform(-0.8, 0.8, size=2),
           'covariance': belief_covariance(rng, kind)}
    neighbour = {'position': ego['position'] - distance * np.array([math.cos(bearing),
                                                                     math.sin(bearing)]),
                 'velocity': rng.uniform(-0.8, 0.8, size=2),
                 'covariance': belief_covariance(rng, kind)}
    actuation = np.diag(rng.uniform(0.0, 0.02, size=2) ** 2)
    case = {'ego': ego, 'neighbour': neighbour, 'actuation': actuation, 'share': share,
            'radius': radius}
    # The mean relative velocity: slow (a broad direction) or passing the neighbour at a
    # chosen miss distance, so that the probabilities spread over (0, 1).
    relative = ego['position'] - neighbour['position']
    if kind == 'slow':
        mean_w = rng.normal(scale=0.1, size=2)
    else:
        miss = min(rng.uniform(0.0, 2.0 * radius), 0.99 * distance)
        turn = math.asin(miss / distance) * rng.choice([-1.0, 1.0])
        heading = math.atan2(-relative[1], -relative[0]) + turn
        mean_w = rng.uniform(0.4, 2.0) * np.array([math.cos(heading), math.sin(heading)])
    rho = 1.0 - share
    case['command'] = rho * (mean_w + (1.0 - rho) / rho * ego['velocity']
                             + neighbour['velocity'])
    return case


def relative_gaussian(case):
    """Mean and covariance of ``z = (r, w)`` as the linear map of ``(p_i, v_i, p_j, v_j, eps)``."""
    rho = 1.0 - case['share']
    ego, neighbour = case['ego'], case['neighbour']
    mean_x = np.concatenate([ego['position'], ego['velocity'], neighbour['position'],
                             neighbour['velocity'], np.zeros(2)])
    cov_x = np.zeros((10, 10))
    cov_x[:4, :4], cov_x[4:8, 4:8] = ego['covariance'], neighbour['covariance']
    cov_x[8:, 8:] = case['actuation']
    identity = np.eye(2)
    linear = np.zeros((4, 10))
    linear[:2, 0:2], linear[:2, 4:6] = identity, -identity
    linear[2:, 2:4] = -(1.0 - rho) / rho * identity
    linear[2:, 6:8] = -identity
    linear[2:, 8:10] = identity / rho
    offset = np.concatenate([np.zeros(2), case['command'] / rho])
    return linear @ mean_x + offset, linear @ cov_x @ linear.T


def sampled_probabilities(rng, case, count):
    """Sample the beliefs and the noise; return the fractions with ``f >= 0`` and ``g >= 0``."""
    ego, neighbour = case['ego'], case['neighbour']
    draws = []
    for mean, covariance in ((np.r_[ego['position'], ego['velocity']], ego['covariance']),
                             (np.r_[neighbour['position'], neighbour['velocity']],
                              neighbour['covariance']),
                             (np.zeros(2), case['actuation'])):
        draws.append(mean + rng.standard_normal((count, mean.size)) @ square_root(covariance).T)
    ego_state, neighbour_state, noise = draws
    rho = 1.0 - case['share']
    r = ego_state[:, :2] - neighbour_state[:, :2]
    w = ((case['command'] + noise - (1.0 - rho) * ego_state[:, 2:]) / rho
         - neighbour_state[:, 2:])
    cross = r[:, 0] * w[:, 1] - r[:, 1] * w[:, 0]
    f = cross * cross - case['radius'] ** 2 * np.sum(w * w, axis=1)
    return np.mean(f >= 0.0), np.mean(np.sum(r * w, axis=1) >= 0.0)


def sampled_condition(rng, case, count, horizon):
    """Sample as above; return the fraction with ``f >= 0 or g >= 0 or (h1 >= 0 and h2 >= 0)``.

    ``h1 = -(r . w) - tau |w|^2`` (the closest approach is beyond ``tau``) and ``h2 = |r + tau
    w|^2 - R^2`` (the robots are ``R`` apart at ``tau``), written out on the samples.
    """
    ego, neighbour = case['ego'], case['neighbour']
    draws = []
    for mean, covariance in ((np.r_[ego['position'], ego['velocity']], ego['covariance']),
                             (np.r_[neighbour['position'], neighbour['velocity']],
                              neighbour['covariance']),
                             (np.zeros(2), case['actuation'])):
        draws.append(mean + rng.standard_normal((count, mean.size)) @ square_root(covariance).T)
    ego_state, neighbour_state, noise = draws
    rho = 1.0 - case['share']
    r = ego_state[:, :2] - neighbour_state[:, :2]
    w = ((case['command'] + noise - (1.0 - rho) * ego_state[:, 2:]) / rho
         - neighbour_state[:, 2:])
    cross = r[:, 0] * w[:, 1] - r[:, 1] * w[:, 0]
    speed_sq = np.sum(w * w, axis=1)
    closing = np.sum(r * w, axis=1)
    at_horizon = r + horizon * w
    event = ((cross * cross - case['radius'] ** 2 * speed_sq >= 0.0) | (closing >= 0.0)
             | ((-closing - horizon * speed_sq >= 0.0)
                & (np.sum(at_horizon * at_horizon, axis=1) >= case['radius'] ** 2)))
    return np.mean(event)


def cases_of(seed, kinds, per_kind):
    """``per_kind`` encounters of every kind, shares 0 and 1/2 alternating."""
    rng = np.random.default_rng(seed)
    return [random_case(rng, kind, 0.5 * (index % 2)) for kind in kinds
            for index in range(per_kind)]


def stacked(cases):
    """Stack the relative Gaussians and radii of CASES for one batched call."""
    gaussians = [relative_gaussian(case) for case in cases]
    return (np.array([mean for mean, _ in gaussians]), np.array([cov for _, cov in gaussians]),
            np.array([case['radius'] for case in cases]))


def at_cantelli_edge(case, k):
    """
    Turn the mean relative velocity away from the neighbour to where ``E[f] >= k sd[f]`` starts.

    Return the case with the command that gives it, or None. This is where the planner's choice
    lies when the constraint binds, and where it asks for a certificate.
    """
    mean, cov = relative_gaussian(case)
    heading = math.atan2(-mean[1], -mean[0])
    turns = heading + np.linspace(0.0, 0.5 * math.pi, 400)
    means = np.repeat(mean[None, :], turns.size, axis=0)
    means[:, 2:] = math.hypot(mean[2], mean[3]) * np.stack([np.cos(turns), np.sin(turns)], 1)
    expectation, variance = rvo_moments(means, cov, case['radius'])
    margin = expectation - k * np.sqrt(variance)
    crossing = np.flatnonzero((margin[:-1] < 0.0) & (margin[1:] >= 0.0))
    if crossing.size == 0:
        return None
    rho = 1.0 - case['share']
    edge = dict(case)
    edge['command'] = rho * (means[crossing[0] + 1, 2:] + (1.0 - rho) / rho
                             * case['ego']['velocity'] + case['neighbour']['velocity'])
    return edge


def test_bound_never_exceeds_the_sampled_probability():
    cases = cases_of(21, KINDS, 108)
    means, covs, radii = stacked(cases)
    certificate = rvo_certificate(means, covs, radii)
    gate = receding_certificate(means, covs)
    rng = np.random.default_rng(22)
    samples = 16_000
    for index, case in enumerate(cases):
        sampled_f, sampled_g = sampled_probabilities(rng, case, samples)
        for bound, sampled in ((certificate.probability[index], sampled_f),
                               (gate.probability[index], sampled_g)):
            assert sampled >= bound - Z * math.sqrt(bound * (1.0 - bound) / samples) - 1e-6, (
                index, case['share'], bound, sampled)
    assert len(cases) >= 500
    # The cases are informative: many probabilities well inside (0, 1), and the wedge bound in
    # charge of most of them.
    inside = (certificate.probability > 0.05) & (certificate.probability < 0.95)
    assert np.count_nonzero(inside) >= 60
    assert np.mean(certificate.method == 'wedge') >= 0.8


def test_horizon_bound_never_exceeds_the_sampled_probability_of_the_condition():
    # The whole condition with the gate and a horizon of 1-5 s: the horizon bound is a lower
    # bound on its probability, and where the closest approach lies beyond the horizon it is
    # the only Gaussian bound that sees it.
    cases = cases_of(61, KINDS, 100)
    means, covs, radii = stacked(cases)
    horizons = np.random.default_rng(62).choice([1.0, 2.5, 5.0], size=len(cases))
    bounds = horizon_certificate(means, covs, radii, horizons)
    others = np.maximum(rvo_certificate(means, covs, radii).probability,
                        receding_certificate(means, covs).probability)
    rng = np.random.default_rng(63)
    samples = 16_000
    sampled = np.array([sampled_condition(rng, case, samples, horizon)
                        for case, horizon in zip(cases, horizons, strict=True)])
    allowed = Z * np.sqrt(bounds * (1.0 - bounds) / samples) + 1e-6
    worst = int(np.argmax(bounds - sampled - allowed))
    assert np.all(sampled >= bounds - allowed), (worst, bounds[worst], sampled[worst])
    assert len(cases) >= 500
    # Informative: many bounds well inside (0, 1), and many above both other bounds by 0.05.
    assert np.count_nonzero((bounds > 0.05) & (bounds < 0.95)) >= 40
    assert np.count_nonzero(bounds > others + 0.05) >= 50


def test_horizon_bound_is_close_for_a_collision_beyond_the_horizon():
    # Head-on at 8 m closing at 1.6 m/s (contact after 4.6 s), horizon 2.5 s: the condition
    # holds through the horizon pair with probability near 1; the f and g bounds see little.
    belief = np.diag([0.05 ** 2] * 4)
    case = {'ego': {'position': np.zeros(2), 'velocity': np.array([0.8, 0.0]),
                    'covariance': belief},
            'neighbour': {'position': np.array([8.0, 0.0]), 'velocity': np.array([-0.8, 0.0]),
                          'covariance': belief},
            'actuation': np.zeros((2, 2)), 'share': 0.5, 'radius': 0.6,
            'command': np.array([0.8, 0.0])}
    mean, cov = relative_gaussian(case)
    bound = float(horizon_certificate(mean, cov, 0.6, 2.5))
    sampled = sampled_condition(np.random.default_rng(64), case, 200_000, 2.5)
    assert float(rvo_certificate(mean, cov, 0.6).probability) < 0.1
    assert float(receding_certificate(mean, cov).probability) < 0.1
    assert sampled - 1e-3 <= bound <= sampled + 4.0 * math.sqrt(
        max(sampled * (1.0 - sampled), 1e-6) / 200_000)


def test_horizon_bound_rejects_bad_horizons():
    for horizon in (0.0, -1.0, math.inf):
        with pytest.raises(ValueError, match='horizon'):
            horizon_certificate(np.zeros(4), np.eye(4), 0.5, horizon)


@pytest.mark.parametrize('k, median_gap, high_gap', [(1.0, 0.04, 0.07), (2.0, 0.003, 0.01)])
def test_bound_rises_towards_the_sampled_probability_as_wedges_are_added(k, median_gap, high_gap):
    rng = np.random.default_rng(int(31 * k))
    edges = [at_cantelli_edge(case, k) for case in cases_of(32, ('filter', 'isotropic'), 30)]
    edges = [edge for edge in edges if edge is not None]
    means, covs, radii = stacked(edges)
    bounds = np.array([rvo_certificate(means, covs, radii, wedges=wedges).probability
                       for wedges in (8, 16, 32, 64, 128)])
    # Doubling the wedges refines the cut: the bound never falls (beyond rounding).
    assert np.all(np.diff(bounds, axis=0) >= -1e-12)
    sampled = np.array([sampled_probabilities(rng, edge, 100_000)[0] for edge in edges])
    gaps = sampled[None, :] - bounds
    median, high = np.median(gaps, axis=1), np.percentile(gaps, 90, axis=1)
    print(f'k = {k}, wedges 8..128: median gap {np.round(median, 4)}, 90th percentile '
          f'{np.round(high, 4)}')
    assert len(edges) >= 40
    assert median[-1] <= median_gap and high[-1] <= high_gap
    # Once the wedges resolve the mass (from 32 on), the gap closes at the first-order rate:
    # halved, or nearly, per doubling.
    assert np.all(np.diff(median) <= 0.0)
    assert np.all(median[3:] <= 0.65 * median[2:-1] + 2e-4)


def head_on(k):
    """Head-on at 2.5 m, R = 0.6, every std 0.05, at the ``k`` edge of a sideways escape."""
    position_std = velocity_std = 0.05
    belief = np.diag([position_std ** 2] * 2 + [velocity_std ** 2] * 2)
    case = {'ego': {'position': np.zeros(2), 'velocity': np.array([0.8, 0.0]),
                    'covariance': belief},
            'neighbour': {'position': np.array([2.5, 0.0]), 'velocity': np.array([-0.8, 0.0]),
                          'covariance': belief},
            'actuation': np.zeros((2, 2)), 'share': 0.5, 'radius': 0.6}
    # Commands turning left of the head-on line at 0.8 m/s: the first that meets the margin.
    for turn in np.linspace(0.0, 1.2, 1201):
        case['command'] = 0.8 * np.array([math.cos(turn), math.sin(turn)])
        mean, cov = relative_gaussian(case)
        expectation, variance = rvo_moments(mean, cov, 0.6)
        if expectation - k * math.sqrt(variance) >= 0.0:
            return case, mean, cov
    raise AssertionError('no escape meets the margin')


def test_head_on_at_cantellis_edge_certifies_what_sampling_finds():
    case, mean, cov = head_on(2.0)
    certificate = rvo_certificate(mean, cov, 0.6)
    sampled, _ = sampled_probabilities(np.random.default_rng(41), case, 400_000)
    print(f'head-on at k = 2: Cantelli 0.8, certified {float(certificate.probability):.4f}, '
          f'sampled {sampled:.4f}')
    assert certificate.method == 'wedge'
    assert sampled >= 0.98
    assert sampled - 0.01 <= certificate.probability <= sampled + 4.0 * math.sqrt(
        sampled * (1.0 - sampled) / 400_000)


def test_bound_is_much_tighter_than_cantelli_at_its_edges():
    cases = cases_of(51, ('filter', 'isotropic'), 40)
    for k, cantelli in ((1.0, 0.5), (2.0, 0.8), (3.0, 0.9)):
        edges = [edge for edge in (at_cantelli_edge(case, k) for case in cases)
                 if edge is not None]
        certificate = rvo_certificate(*stacked(edges))
        probability = certificate.probability
        print(f'k = {k}: Cantelli {cantelli}, certified median {np.median(probability):.4f}, '
              f'10th percentile {np.percentile(probability, 10):.4f}')
        assert len(edges) >= 50
        # Never below Cantelli's bound (it is the floor of the certificate).
        assert np.all(probability >= cantelli - 1e-6)
        assert np.mean(certificate.method == 'wedge') >= 0.9
        assert np.median(probability) >= cantelli + 0.6 * (1.0 - cantelli)


@pytest.mark.parametrize('holds', [True, False])
def test_zero_covariance_gives_the_deterministic_answer(holds):
    # The mean line passes 1 m (holds) or 0.3 m (not) from the neighbour, R = 0.6.
    offset = 1.0 if holds else 0.3
    mean = np.array([-3.0, offset, 1.2, 0.0])
    certificate = rvo_certificate(mean, np.zeros((4, 4)), 0.6)
    assert certificate.method == 'deterministic'
    assert float(certificate.probability) == (1.0 if holds else 0.0)
    # The limit of shrinking covariances is the same answer.
    rng = np.random.default_rng(61)
    factor = rng.normal(size=(4, 4))
    for scale in (1e-3, 1e-5):
        shrunk = rvo_certificate(mean, scale ** 2 * factor @ factor.T, 0.6)
        if holds:
            assert shrunk.method == 'wedge' and float(shrunk.probability) >= 1.0 - 1e-6
        else:
            # Both bounds are 0 here; whichever is reported, it is 0.
            assert float(shrunk.probability) == 0.0
    gate = receding_certificate(mean, np.zeros((4, 4)))
    assert gate.method == 'deterministic' and float(gate.probability) == 0.0


def test_known_velocity_is_the_exact_folded_normal():
    rng = np.random.default_rng(71)
    for _ in range(20):
        mean = np.r_[rng.uniform(-3.0, 3.0, size=2), rng.normal(size=2)]
        cov = np.zeros((4, 4))
        factor = rng.normal(scale=0.2, size=(2, 2))
        cov[:2, :2] = factor @ factor.T
        certificate = rvo_certificate(mean, cov, 0.5)
        assert certificate.method == 'known-velocity'
        r = mean[:2] + rng.standard_normal((200_000, 2)) @ square_root(cov[:2, :2]).T
        w = mean[2:]
        sampled = np.mean((r[:, 0] * w[1] - r[:, 1] * w[0]) ** 2 >= 0.25 * (w @ w))
        standard_error = math.sqrt(max(sampled * (1.0 - sampled), 1e-6) / 200_000)
        assert abs(float(certificate.probability) - sampled) <= Z * standard_error
    # No relative motion at all: f = 0 holds.
    standing = rvo_certificate(np.array([1.0, 0.0, 0.0, 0.0]), np.diag([0.1, 0.1, 0.0, 0.0]),
                               2.0)
    assert standing.method == 'known-velocity' and float(standing.probability) == 1.0


def test_known_velocity_bounds_are_the_exact_probabilities_less_the_slack():
    # With S_ww = 0 both bounds are the exact probabilities of a normal r less SLACK:
    # P(|r . n| >= R) for mu_w's unit normal n and P(r . mu_w >= 0), here in mpmath at 30 digits.
    rng = np.random.default_rng(72)
    with mpmath.workdps(30):
        for _ in range(40):
            mean = np.r_[rng.uniform(-3.0, 3.0, size=2), rng.normal(size=2)]
            cov = np.zeros((4, 4))
            factor = rng.normal(scale=rng.choice([0.02, 0.2, 1.0]), size=(2, 2))
            cov[:2, :2] = factor @ factor.T
            radius = rng.uniform(0.2, 1.0)
            r_x, r_y, w_x, w_y = (mpmath.mpf(float(value)) for value in mean)
            s_xx, s_xy, s_yy = (mpmath.mpf(float(value)) for value in
                                (cov[0, 0], cov[0, 1], cov[1, 1]))
            speed = mpmath.sqrt(w_x ** 2 + w_y ** 2)
            n_x, n_y = w_y / speed, -w_x / speed
            offset = r_x * n_x + r_y * n_y
            spread = mpmath.sqrt(n_x ** 2 * s_xx + 2 * n_x * n_y * s_xy + n_y ** 2 * s_yy)
            exact_f = (mpmath.ncdf((offset - radius) / spread)
                       + mpmath.ncdf((-offset - radius) / spread))
            closing = r_x * w_x + r_y * w_y
            exact_g = mpmath.ncdf(closing / mpmath.sqrt(w_x ** 2 * s_xx + 2 * w_x * w_y * s_xy
                                                        + w_y ** 2 * s_yy))
            rvo = rvo_certificate(mean, cov, radius)
            gate = receding_certificate(mean, cov)
            assert rvo.method == gate.method == 'known-velocity'
            for bound, exact in ((rvo, exact_f), (gate, exact_g)):
                exact = min(float(exact), 1.0)
                assert float(bound.probability) <= exact
                assert float(bound.probability) == pytest.approx(max(exact - SLACK, 0.0),
                                                                 abs=1e-13)


def test_the_condition_bound_rejects_bad_arguments():
    mean, cov = np.zeros((2, 4)), np.stack([np.eye(4)] * 2)
    radius, required, gated = np.full(2, 0.5), np.full(2, 0.9), np.ones(2, dtype=bool)
    assert condition_bound(mean, cov, radius, required, gated, 2.0).shape == (2,)
    with pytest.raises(ValueError, match='finite'):
        condition_bound(np.array([[0.0, 0.0, np.inf, 1.0]] * 2), cov, radius, required, gated)
    with pytest.raises(ValueError, match='finite'):
        condition_bound(mean, cov * np.nan, radius, required, gated)
    with pytest.raises(ValueError, match='shape'):
        condition_bound(mean, cov, np.full(3, 0.5), required, gated)
    with pytest.raises(ValueError, match='one value per entry'):
        condition_bound(mean, cov, radius, np.full(3, 0.9), gated)
    with pytest.raises(ValueError, match='wedges'):
        condition_bound(mean, cov, radius, required, gated, wedges=6.0)


def test_singular_velocity_covariance_with_cross_terms_falls_back_to_cantelli():
    # w varies along x only, and r_y with it: after the shift a cross-covariance is left that
    # the singular S_ww cannot explain by an inverse.
    cov = np.zeros((4, 4))
    cov[:2, :2] = np.diag([0.02, 0.03])
    cov[2, 2] = 0.04
    cov[1, 2] = cov[2, 1] = 0.02
    mean = np.array([-3.0, 1.5, 1.0, 0.1])
    certificate = rvo_certificate(mean, cov, 0.6)
    expectation, variance = rvo_moments(mean, cov, 0.6)
    cantelli = expectation ** 2 / (expectation ** 2 + variance)
    assert certificate.method == 'cantelli'
    assert float(certificate.probability) == pytest.approx(cantelli - SLACK, abs=1e-12)
    # A singular S_ww without cross terms keeps the wedge bound, which must hold.
    cov[1, 2] = cov[2, 1] = 0.0
    z = mean + np.random.default_rng(81).standard_normal((200_000, 4)) @ square_root(cov).T
    cross = z[:, 0] * z[:, 3] - z[:, 1] * z[:, 2]
    sampled = np.mean(cross ** 2 >= 0.36 * (z[:, 2] ** 2 + z[:, 3] ** 2))
    plain = rvo_certificate(mean, cov, 0.6)
    assert plain.method == 'wedge'
    assert sampled - 0.01 <= float(plain.probability) <= sampled + 1e-3


def test_batches_give_each_entry_its_own_certificate():
    cases = cases_of(91, ('typical', 'isotropic', 'slow'), 4)
    means, covs, radii = stacked(cases)
    batch = rvo_certificate(means.reshape(3, 4, 4), covs.reshape(3, 4, 4, 4),
                            radii.reshape(3, 4))
    assert batch.probability.shape == batch.method.shape == (3, 4)
    assert set(batch.method.ravel()) <= set(METHODS)
    for index in range(len(cases)):
        single = rvo_certificate(means[index], covs[index], radii[index])
        assert single.probability.shape == ()
        # Exactly: an entry's bound does not depend on the others in its batch, those with a
        # cross-covariance left ('typical') and without ('isotropic') alike.
        assert float(single.probability) == batch.probability.ravel()[index]
    # One covariance and one radius for many means broadcast.
    shared = rvo_certificate(means, covs[0], 0.7)
    assert shared.probability.shape == (len(cases),)


@pytest.mark.parametrize('horizon', [2.5, None])
def test_bounds_until_short_are_the_batch_bounds_up_to_the_first_short_entry(horizon):
    # The oracle: one call over every entry, its first short entry found by hand.
    cases = cases_of(97, KINDS, 8)
    means, covs, radii = stacked(cases)
    rng = np.random.default_rng(98)
    gated = rng.random(len(cases)) < 0.7
    full = condition_bound(means, covs, radii, np.ones(len(cases)), gated, horizon)
    # Nothing short; short from the middle on (the first of two made short); every one short.
    middle = len(cases) // 2
    reachable = 0.5 * full
    beyond = reachable.copy()
    beyond[[middle, middle + 3]] = np.minimum(full[[middle, middle + 3]] + 0.01, 1.0)
    for required, first_short in ((reachable, None), (beyond, middle),
                                  (np.ones(len(cases)), 0)):
        expected = condition_bound(means, covs, radii, required, gated, horizon)
        short = np.flatnonzero(expected < required)
        assert (short[0] if short.size else None) == first_short
        bounds, done = condition_bound_until_short(means, covs, radii, required, gated, horizon)
        assert done == (short[0] + 1 if short.size else len(cases))
        assert np.array_equal(bounds[:done], expected[:done])
        assert not bounds[done:].any()


@pytest.mark.parametrize('horizon', [2.5, None])
def test_the_condition_bound_is_the_three_certificates_each_where_the_others_fall_short(horizon):
    # condition_bound computes the wedges once for f and g and each later bound only where the
    # earlier ones leave an entry short; the oracle calls the three public certificates, each on
    # the entries it is due for, as separate batches.
    cases = cases_of(95, KINDS, 30)
    means, covs, radii = stacked(cases)
    rng = np.random.default_rng(96)
    required = rng.uniform(0.5, 0.999, size=len(cases))
    gated = rng.random(len(cases)) < 0.7
    expected = rvo_certificate(means, covs, radii).probability
    gate = gated & (expected < required)
    expected[gate] = np.maximum(expected[gate],
                                receding_certificate(means[gate], covs[gate]).probability)
    later = gate & (expected < required)
    if horizon is not None:
        expected[later] = np.maximum(expected[later], horizon_certificate(
            means[later], covs[later], radii[later], horizon))
    bounds = condition_bound(means, covs, radii, required, gated, horizon)
    assert bounds.shape == (len(cases),)
    assert np.max(np.abs(bounds - expected)) <= 1e-12
    # Informative: the receding bound and the horizon bound are both needed for some entries.
    assert np.count_nonzero(gate) >= 20 and np.count_nonzero(later) >= 10
    # Nothing short: f alone.
    assert np.array_equal(condition_bound(means, covs, radii, np.zeros(len(cases)), gated,
                                          horizon),
                          rvo_certificate(means, covs, radii).probability)


def test_harmonic_ranges_are_the_extremes_of_the_sinusoids_over_each_wedge():
    # Dense samples of c cos(m x) + s sin(m x) over each wedge, m = 1 or 2, ends included: the
    # range contains every sample and exceeds them by at most the curvature between samples.
    rng = np.random.default_rng(97)
    count, steps = 400, 4001
    starts = rng.uniform(0.0, math.pi, size=count)
    widths = rng.uniform(0.0, math.pi, size=count) * (rng.random(count) < 0.9)
    coefficients = rng.normal(size=(count, 2))
    for index in range(count):
        (c, s), start, width = coefficients[index], starts[index], widths[index]
        for multiple in (1.0, 2.0):
            low, high = harmonic_range(c, s, multiple, start, width)
            x = start + width * np.linspace(0.0, 1.0, steps)
            values = c * np.cos(multiple * x) + s * np.sin(multiple * x)
            slack = math.hypot(c, s) * (multiple * width / (steps - 1)) ** 2
            assert values.min() - slack - 1e-12 <= low <= values.min() + 1e-12
            assert values.max() - 1e-12 <= high <= values.max() + slack + 1e-12


def test_wedge_masses_never_exceed_the_sampled_masses_of_the_direction():
    # The compiled cut's lower bounds on the probability that the direction of w falls in each
    # wedge and in its opposite, against the fractions of sampled w (an own sampler).
    rng = np.random.default_rng(98)
    cases = cases_of(99, KINDS, 4)
    means, covs, _ = stacked(cases)
    pairs, count = 16, 200_000
    start, width, masses, invertible = cut_wedges(means, covs, pairs)
    assert start.shape == width.shape == (len(cases), pairs)
    assert masses.shape == (len(cases), 2 * pairs) and invertible.all()
    assert np.allclose(width.sum(axis=1), math.pi, rtol=0.0, atol=1e-12)
    assert np.all(masses >= 0.0) and np.all(masses.sum(axis=1) <= 1.0 + 1e-12)
    for index in range(len(cases)):
        w = means[index, 2:] + rng.standard_normal((count, 2)) @ square_root(
            covs[index, 2:, 2:]).T
        angle = np.arctan2(w[:, 1], w[:, 0])
        for side in range(2):
            offset = np.mod(angle - start[index][:, None] - side * math.pi, 2.0 * math.pi)
            sampled = np.mean(offset <= width[index][:, None], axis=1)
            standard_error = np.sqrt(np.maximum(sampled * (1.0 - sampled), 1.0 / count) / count)
            assert np.all(masses[index, side * pairs:(side + 1) * pairs]
                          <= sampled + Z * standard_error)
        # Informative: together the bounds claim most of the mass.
        assert masses[index].sum() >= 0.5


@pytest.mark.parametrize('wedges', [3, 2, 5, MAX_WEDGES + 2, 64.0, True])
def test_invalid_wedges_are_rejected(wedges):
    with pytest.raises(ValueError, match='wedges'):
        rvo_certificate(np.zeros(4), np.eye(4), 0.5, wedges=wedges)


def test_invalid_shapes_and_values_are_rejected():
    with pytest.raises(ValueError, match='shape'):
        rvo_certificate(np.zeros(3), np.eye(4), 0.5)
    with pytest.raises(ValueError, match='finite'):
        receding_certificate(np.array([0.0, 0.0, np.nan, 1.0]), np.eye(4))


def test_the_normal_distribution_functions_the_bounds_use_match_the_c_library():
    # SLACK covers an error of 2e-14 per evaluation of Phi (the module's docstring): scipy's
    # (the horizon and known-velocity bounds) and the compiled one (the wedge bounds).
    x = np.concatenate([np.linspace(-40.0, 40.0, 200_001), [-np.inf, np.inf]])
    reference = np.array([0.5 * math.erfc(-value / math.sqrt(2.0)) for value in x])
    assert np.max(np.abs(ndtr(x) - reference)) <= 2e-14
    assert np.isnan(ndtr(np.nan))
    assert ndtr(np.zeros((2, 3))).shape == (2, 3)
    # The compiled one is erf and erfc of the C library: its oracle is mpmath's, at 40 digits.
    # In the lower tail (where the minima and miss probabilities are) its relative error is
    # that of rounding x / sqrt(2), amplified by d log Phi / dx, about |x|.
    with mpmath.workdps(40):
        for value in np.concatenate([np.linspace(-38.0, 9.0, 4_701), [-np.inf, np.inf]]):
            exact = mpmath.ncdf(mpmath.mpf(float(value)))
            compiled = compiled_ndtr(value)
            assert abs(compiled - exact) <= 2e-14
            if -37.0 <= value < 0.0:
                # (Below -37 Phi is subnormal, its relative precision less.)
                assert abs(compiled - exact) <= 2e-16 * (value * value + 4.0) * exact
    assert math.isnan(compiled_ndtr(math.nan))



def test_short_entries_are_the_velocities_cantelli_leaves_short():
    # Per (velocity, neighbour) Cantelli's k^2 / (1 + k^2) of the achieved margin (1 from
    # k = 1e8 on, 0 for a negative margin); the entries below the required probability,
    # velocity-major, with the mean of z at their velocity and their neighbour's arguments.
    from prvo_core_testing import random_covariance

    from prvo_planner.core.certificate_kernels import short_entries

    rng = np.random.default_rng(41)
    count, velocities_count = 6, 3
    origin = rng.normal(0.0, 2.0, size=(count, 4))
    cov = np.array([random_covariance(rng, 4, 0.1) for _ in range(count)])
    radius = rng.uniform(0.3, 0.8, size=count)
    lead = rng.uniform(1.0, 2.0, size=count)
    gated = np.arange(count) % 2 == 0
    velocities = rng.normal(0.0, 0.7, size=(velocities_count, 2))
    achieved = rng.uniform(-0.5, 6.0, size=(velocities_count, count))
    achieved[0, :3] = [2e8, 1e300, math.inf]
    required = rng.uniform(0.5, 0.99, size=count)
    floors, short, mean, short_cov, short_radius, short_required, short_gated = short_entries(
        origin, lead, cov, radius, velocities, achieved, required, gated)
    expected_floors = [[1.0 if k >= 1e8 else (max(k, 0.0) ** 2 / (1.0 + max(k, 0.0) ** 2))
                        for k in row] for row in achieved]
    np.testing.assert_allclose(floors, expected_floors, rtol=1e-15, atol=0.0)
    expected = [(velocity, neighbour) for velocity in range(velocities_count)
                for neighbour in range(count)
                if expected_floors[velocity][neighbour] < required[neighbour]]
    assert 0 < len(expected) < velocities_count * count
    np.testing.assert_array_equal(short, [velocity * count + neighbour
                                          for velocity, neighbour in expected])
    for entry, (velocity, neighbour) in enumerate(expected):
        np.testing.assert_allclose(
            mean[entry], np.r_[origin[neighbour, :2],
                               origin[neighbour, 2:] + lead[neighbour] * velocities[velocity]],
            rtol=1e-15, atol=1e-15)
        np.testing.assert_array_equal(short_cov[entry], cov[neighbour])
        assert short_radius[entry] == radius[neighbour]
        assert short_required[entry] == required[neighbour]
        assert short_gated[entry] == gated[neighbour]
