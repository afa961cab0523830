"""``plan_velocity`` against brute-force and sampled ground truth."""

import math

from independent import line_clear, relative_samples, rvo_f
import numpy as np
from prvo_core_testing import crowd, crowd_rays, random_covariance, random_two_robot_encounter
import pytest

from prvo_planner.core import (
    AgentBelief,
    PlannerConfig,
    plan_velocity,
    rvo_moments,
)
from prvo_planner.core.encounter import candidate_directions
from prvo_planner.core.feasibility import ray_gaps
from prvo_planner.core.moments import condition_moments
from prvo_planner.core.probability import sample_relative_states

MODELS = ('prvo', 'rvo', 'inflate', 'mc')


def deterministic_f(ego, neighbour, velocity, radius=None):
    """``f`` at the means (section 3), computed directly."""
    radius = ego.radius + neighbour.radius if radius is None else radius
    relative_velocity = 2.0 * np.asarray(velocity) - ego.velocity - neighbour.velocity
    relative_position = np.broadcast_to(ego.position - neighbour.position,
                                        relative_velocity.shape)
    return rvo_f(relative_position, relative_velocity, radius)


@pytest.mark.parametrize('model', MODELS)
@pytest.mark.parametrize('method', ('exact', 'taylor'))
def test_no_neighbours_returns_clipped_preference(model, method):
    ego = AgentBelief([0.0, 0.0], [0.0, 0.0], 0.01 * np.eye(4), 0.3)
    config = PlannerConfig(max_speed=1.5, model=model, method=method, seed=0)
    far = AgentBelief([50.0, 0.0], [0.0, 0.0], 0.01 * np.eye(4), 0.3)
    for neighbours in ([], [far]):
        slow = plan_velocity(ego, neighbours, [0.3, -0.4], config)
        fast = plan_velocity(ego, neighbours, [3.0, 4.0], config)
        np.testing.assert_allclose(slow.velocity, [0.3, -0.4])
        np.testing.assert_allclose(fast.velocity, [0.9, 1.2])
        assert fast.feasible and fast.achieved_k == math.inf and fast.eta_bound == 1.0
        assert fast.num_constraints == 0


def test_noise_free_rvo_satisfies_every_neighbour_when_a_candidate_does():
    rng = np.random.default_rng(21)
    config = PlannerConfig(model='rvo', receding_gate=False, time_horizon=math.inf,
                           num_directions=32, max_speed=1.2)
    speeds = np.linspace(0.0, 1.0, 401)
    checked = 0
    for _ in range(60):
        ego, neighbours = crowd(rng, int(rng.integers(1, 5)), 0.0)
        v_pref = rng.uniform(-1.5, 1.5, size=2)
        result = plan_velocity(ego, neighbours, v_pref, config)
        # Brute force over the same candidate rays.
        directions = candidate_directions(ego, v_pref, config)
        grid = config.max_speed * speeds[None, :, None] * directions[:, None, :]
        satisfied = np.ones(grid.shape[:2], dtype=bool)
        for neighbour in neighbours:
            satisfied &= deterministic_f(ego, neighbour, grid) >= 0.0
        margins = [deterministic_f(ego, neighbour, result.velocity) for neighbour in neighbours]
        if np.any(satisfied):
            checked += 1
            assert result.feasible
            scale = max(abs(deterministic_f(ego, n, np.zeros(2))) for n in neighbours) + 1.0
            assert min(margins) >= -1e-6 * scale
            # Optimal on the rays: no satisfied grid point is closer to v_pref.
            best_grid = np.min(np.linalg.norm(grid[satisfied] - v_pref, axis=-1))
            # 1e-8: the planner keeps its speed 1e-9 v_max inside the feasible interval.
            assert np.linalg.norm(result.velocity - v_pref) <= best_grid + 1e-8
        elif result.feasible:
            assert min(margins) >= -1e-6
    assert checked >= 40


def assert_gaps_match(gap_direction, lower, upper, t, accepted):
    """Assert that the gaps cover exactly the ACCEPTED grid points (M, T), up to 1e-6 at ends."""
    inside = np.zeros_like(accepted)
    near_boundary = np.zeros_like(accepted)
    for direction, low, high in zip(gap_direction, lower, upper, strict=True):
        inside[direction] |= (t >= low) & (t <= high)
        near_boundary[direction] |= (np.abs(t - low) < 1e-6) | (np.abs(t - high) < 1e-6)
    assert np.all((inside == accepted) | near_boundary)


def test_exact_ray_intervals_match_dense_evaluation_of_the_surrogate():
    rng = np.random.default_rng(22)
    t = np.linspace(0.0, 1.0, 2001)
    for _ in range(12):
        ego, neighbours = crowd(rng, int(rng.integers(1, 4)), 0.15)
        config = PlannerConfig(receding_gate=False, time_horizon=math.inf, num_directions=24,
                               k=float(rng.uniform(0.5, 3.0)), actuation_cov=0.01 * np.eye(2))
        encounter, layout, directions, means, variances = crowd_rays(ego, neighbours,
                                                                         config)
        gap_direction, lower, upper = ray_gaps(means, variances, layout.margins(encounter),
                                               layout, 'exact', False, directions[:, 0])
        # Independent: closed-form moments at every grid velocity, no ray polynomials.
        velocities = config.max_speed * t[None, :, None] * directions[:, None, :]
        accepted = np.ones(velocities.shape[:2], dtype=bool)
        for index in range(encounter.origin.shape[0]):
            mean = np.concatenate(np.broadcast_arrays(
                encounter.origin[index, :2], encounter.origin[index, 2:] + 2.0 * velocities),
                axis=-1)
            expectation, variance = rvo_moments(mean, encounter.cov[index],
                                                encounter.combined_radius[index])
            accepted &= expectation - config.k * np.sqrt(np.maximum(variance, 0.0)) >= 0.0
        assert_gaps_match(gap_direction, lower, upper, t, accepted)


@pytest.mark.parametrize('receding_gate, time_horizon',
                         [(True, 3.0), (False, 5.0), (True, math.inf)])
def test_ray_intervals_of_every_condition_match_dense_evaluation(receding_gate, time_horizon):
    # Crowds large enough that neighbours close parts of rays for each other.
    rng = np.random.default_rng(23)
    t = np.linspace(0.0, 1.0, 2001)
    for _ in range(10):
        ego, neighbours = crowd(rng, int(rng.integers(2, 9)), 0.15)
        k = float(rng.uniform(0.5, 3.0))
        config = PlannerConfig(receding_gate=receding_gate, time_horizon=time_horizon,
                               num_directions=24, k=k, actuation_cov=0.01 * np.eye(2))
        encounter, layout, directions, means, variances = crowd_rays(ego, neighbours,
                                                                         config)
        gap_direction, lower, upper = ray_gaps(means, variances, layout.margins(encounter),
                                               layout, 'exact', False, directions[:, 0])
        # Independent: each condition's closed-form moments at every grid velocity, accepted
        # by section 7's rule: f, or g, or (h1 and h2) at k' for eta = k^2 / (1 + k^2), or h3.
        velocities = (config.max_speed * t[None, :, None] * directions[:, None, :]).reshape(-1, 2)
        grid_means, grid_variances = condition_moments(
            encounter.origin, encounter.cov, encounter.combined_radius, velocities,
            time_horizon, receding_gate)
        eta = k * k / (1.0 + k * k)
        margins = [k] + [k] * receding_gate + [math.sqrt((1.0 + eta) / (1.0 - eta))] * (
            2 * math.isfinite(time_horizon)) + [k] * math.isfinite(time_horizon)
        meets = grid_means - np.array(margins) * np.sqrt(np.maximum(grid_variances, 0.0)) >= 0.0
        pair_accepted = meets[..., 0]
        if receding_gate:
            pair_accepted = pair_accepted | meets[..., 1]
        if math.isfinite(time_horizon):
            pair_accepted = pair_accepted | (meets[..., -3] & meets[..., -2]) | meets[..., -1]
        accepted = np.all(pair_accepted, axis=0).reshape(directions.shape[0], t.size)
        assert_gaps_match(gap_direction, lower, upper, t, accepted)


def test_inflate_equals_rvo_without_noise_and_respects_the_enlarged_radius():
    rng = np.random.default_rng(23)
    for _ in range(20):
        ego, neighbours = crowd(rng, 2, 0.0)
        v_pref = rng.uniform(-1.0, 1.0, size=2)
        common = {'receding_gate': False, 'time_horizon': math.inf, 'num_directions': 32}
        rvo = plan_velocity(ego, neighbours, v_pref, PlannerConfig(model='rvo', **common))
        inflate = plan_velocity(ego, neighbours, v_pref, PlannerConfig(model='inflate', **common))
        np.testing.assert_allclose(inflate.velocity, rvo.velocity, atol=1e-12)
    for _ in range(20):
        ego, neighbours = crowd(rng, 2, 0.1)
        config = PlannerConfig(model='inflate', eta=0.9, receding_gate=False,
                               time_horizon=math.inf, num_directions=32)
        result = plan_velocity(ego, neighbours, rng.uniform(-1.0, 1.0, size=2), config)
        if result.feasible:
            for neighbour in neighbours:
                spread = np.linalg.eigvalsh(ego.covariance[:2, :2]
                                            + neighbour.covariance[:2, :2])[-1]
                radius = ego.radius + neighbour.radius \
                    + np.sqrt(-2.0 * np.log(1.0 - 0.9)) * np.sqrt(spread)
                assert deterministic_f(ego, neighbour, result.velocity, radius) >= -1e-6


def test_monte_carlo_baseline_meets_eta_under_independent_sampling():
    rng = np.random.default_rng(24)
    config = PlannerConfig(model='mc', eta=0.8, receding_gate=False, time_horizon=math.inf,
                           num_directions=16, mc_samples=4000, seed=5,
                           actuation_cov=0.005 * np.eye(2))
    samples = 20_000
    for _ in range(10):
        ego, neighbour = random_two_robot_encounter(rng)
        result = plan_velocity(ego, [neighbour], [1.0, 0.0], config)
        if result.feasible:
            r, u = relative_samples(rng, ego, neighbour, result.velocity, config.actuation_cov,
                                    samples)
            probability = np.mean(line_clear(r, u, ego.radius + neighbour.radius))
            # The planner's estimate (4000 samples) and ours (20000) both err.
            error = math.sqrt(0.8 * 0.2 / 4000) + math.sqrt(0.8 * 0.2 / samples)
            assert probability >= 0.8 - 4.0 * error


def test_joint_risk_bounds_the_probability_that_all_constraints_hold():
    rng = np.random.default_rng(25)
    eta, samples = 0.8, 20_000
    config = PlannerConfig(eta=eta, risk='joint', receding_gate=False, time_horizon=math.inf,
                           num_directions=32, actuation_cov=0.005 * np.eye(2))
    checked = 0
    for _ in range(15):
        ego, neighbours = crowd(rng, 3, 0.08)
        result = plan_velocity(ego, neighbours, rng.uniform(-1.0, 1.0, size=2), config)
        if not result.feasible:
            continue
        checked += 1
        # Shared ego and actuation samples: the events of different neighbours are dependent.
        ego_state = rng.multivariate_normal(np.r_[ego.position, ego.velocity], ego.covariance,
                                            size=samples)
        command = result.velocity + rng.multivariate_normal(np.zeros(2), config.actuation_cov,
                                                            size=samples)
        all_hold = np.ones(samples, dtype=bool)
        for neighbour in neighbours:
            other = rng.multivariate_normal(np.r_[neighbour.position, neighbour.velocity],
                                            neighbour.covariance, size=samples)
            z = np.concatenate([ego_state[:, :2] - other[:, :2],
                                2.0 * command - ego_state[:, 2:] - other[:, 2:]], axis=1)
            all_hold &= line_clear(z[:, :2], z[:, 2:], ego.radius + neighbour.radius)
        assert all_hold.mean() >= eta - 4.0 * math.sqrt(eta * (1.0 - eta) / samples)
    assert checked >= 5


def test_sampler_matches_the_relative_gaussian_of_section_2():
    rng = np.random.default_rng(26)
    ego = AgentBelief([0.0, 0.0], [0.5, 0.0], random_covariance(rng, 4, 0.3), 0.3)
    neighbour = AgentBelief([3.0, 1.0], [-0.5, 0.1], random_covariance(rng, 4, 0.3), 0.4)
    actuation = 0.02 * np.eye(2)
    command = np.array([0.4, 0.2])
    z = sample_relative_states(ego, neighbour, command, actuation, 200_000, rng)
    # z = M (p_i, v_i, p_j, v_j, a) + (0, 2 v_c): r = p_i - p_j, u = 2 (v_c + a) - v_i - v_j.
    identity, zero = np.eye(2), np.zeros((2, 2))
    linear = np.block([[identity, zero, -identity, zero, zero],
                       [zero, -identity, zero, -identity, 2.0 * identity]])
    joint = np.zeros((10, 10))
    joint[:4, :4], joint[4:8, 4:8], joint[8:, 8:] = ego.covariance, neighbour.covariance, actuation
    expected_mean = np.r_[ego.position - neighbour.position,
                          2.0 * command - ego.velocity - neighbour.velocity]
    np.testing.assert_allclose(z.mean(axis=0), expected_mean, atol=0.01)
    np.testing.assert_allclose(np.cov(z.T), linear @ joint @ linear.T, atol=0.02)


def head_on(heading):
    """Ego at the origin and a neighbour 4 m ahead along HEADING (+1 or -1), closing at 2 m/s."""
    ego = AgentBelief([0.0, 0.0], [heading, 0.0], np.zeros((4, 4)), 0.3)
    neighbour = AgentBelief([4.0 * heading, 0.0], [-heading, 0.0], np.zeros((4, 4)), 0.3)
    return ego, [neighbour], np.array([heading, 0.0])


@pytest.mark.parametrize('heading', (1.0, -1.0))
def test_passing_bias_passes_a_head_on_neighbour_on_the_right(heading):
    ego, neighbours, v_pref = head_on(heading)
    result = plan_velocity(ego, neighbours, v_pref, PlannerConfig(model='rvo', passing_bias=0.1))
    assert result.feasible
    # Right of the preferred direction: -y heading +x, +y heading -x.
    assert heading * result.velocity[1] < -0.05


@pytest.mark.parametrize('side', (1.0, -1.0))
def test_inertia_keeps_the_side_of_the_previous_command(side):
    ego, neighbours, v_pref = head_on(1.0)
    config = PlannerConfig(model='rvo', inertia=0.5, passing_bias=0.1)
    result = plan_velocity(ego, neighbours, v_pref, config, previous=[0.9, 0.35 * side])
    assert result.feasible and side * result.velocity[1] > 0.05
    # Without a previous command the term is off.
    plain = plan_velocity(ego, neighbours, v_pref, PlannerConfig(model='rvo'), previous=None)
    np.testing.assert_allclose(
        plan_velocity(ego, neighbours, v_pref, PlannerConfig(model='rvo', inertia=0.5)).velocity,
        plain.velocity)


def ranked_cost(velocity, v_pref, previous, progress):
    """Return the choice cost with inertia 0.6, passing bias 0.2 and PROGRESS, directly."""
    heading = v_pref / np.hypot(*v_pref)
    left = heading[0] * velocity[1] - heading[1] * velocity[0]
    return ((1.0 - progress) * np.linalg.norm(velocity - v_pref)
            + progress * abs(np.hypot(*v_pref) - velocity @ heading)
            + 0.6 * np.linalg.norm(velocity - previous) + 0.2 * max(left, 0.0))


@pytest.mark.parametrize('progress', (0.0, 0.5))
@pytest.mark.parametrize('model', ('prvo', 'rvo', 'inflate'))
def test_cost_terms_only_rank_velocities_that_meet_the_constraints(model, progress):
    rng = np.random.default_rng(5)
    for _ in range(30):
        ego, neighbours = crowd(rng, 4, 0.05 if model == 'prvo' else 0.0)
        v_pref, previous = rng.uniform(-1.0, 1.0, 2), rng.uniform(-1.0, 1.0, 2)
        plain = plan_velocity(ego, neighbours, v_pref, PlannerConfig(model=model, k=1.0))
        ranked = plan_velocity(ego, neighbours, v_pref, PlannerConfig(
            model=model, k=1.0, inertia=0.6, passing_bias=0.2, progress_weight=progress),
            previous=previous)
        assert ranked.candidates_feasible == plain.candidates_feasible
        if plain.feasible:
            assert ranked.feasible and ranked.achieved_k >= 1.0 - 1e-6
        assert np.hypot(*ranked.velocity) <= 1.0 + 1e-12
        # The ranked choice is no worse under its own cost than the plain one.
        if plain.feasible:
            assert (ranked_cost(ranked.velocity, v_pref, previous, progress)
                    <= ranked_cost(plain.velocity, v_pref, previous, progress) + 1e-9)


@pytest.mark.parametrize('field, value', [('inertia', 1.0), ('inertia', -0.1),
                                          ('passing_bias', -0.1), ('progress_weight', 1.0),
                                          ('progress_weight', -0.1)])
def test_choice_cost_weights_are_validated(field, value):
    with pytest.raises(ValueError, match=field):
        PlannerConfig(**{field: value})


@pytest.mark.parametrize('count', [64, 12, 10])
@pytest.mark.parametrize('seed', [None, 3])
def test_candidate_headings_are_even_and_opposite_ones_exactly_opposite(count, seed):
    config = PlannerConfig(num_directions=count, seed=seed)
    ego = AgentBelief([0.0, 0.0], [0.0, 0.0], np.zeros((4, 4)), 0.25)
    # A zero preference and a zero velocity add no direction: the grid alone.
    directions = candidate_directions(ego, np.zeros(2), config)
    angles = np.unwrap(np.arctan2(directions[:, 1], directions[:, 0]))
    np.testing.assert_allclose(np.hypot(*directions.T), 1.0, rtol=0.0, atol=1e-15)
    np.testing.assert_allclose(np.diff(angles), 2.0 * math.pi / count, rtol=0.0, atol=1e-12)
    if count % 4 == 0:
        # Two robots facing each other see mirror images, bit for bit (sin(pi) is not 0).
        np.testing.assert_array_equal(directions[count // 2:], -directions[:count // 2])
        if seed is None:
            np.testing.assert_array_equal(directions[::count // 4],
                                          [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
