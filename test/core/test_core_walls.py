"""Planning against static obstacles: walls, wall ends, doorways, polygons and discs."""

import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.stats import norm

from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocities, plan_velocity
from prvo_planner.core.obstacles import StaticObstacles
from prvo_planner.core.walls import wall_model
from prvo_planner.parameters import ParameterError, check_parameter
from prvo_sim.bench.doors import door_approach

HORIZON = 2.0
EGO_RADIUS = 0.25
SAMPLES = 4000


def obstacles(segments=(), half_widths=None, centres=(), radii=()):
    segments = np.array(segments, dtype=float).reshape(-1, 2, 2)
    return StaticObstacles(segments, np.zeros(len(segments)) if half_widths is None
                           else np.array(half_widths, dtype=float),
                           np.array(centres, dtype=float).reshape(-1, 2),
                           np.array(radii, dtype=float))


def point_segment_distance(points, start, end):
    """Distance of POINTS (..., 2) from the segment [START, END] (the test's own geometry)."""
    along = end - start
    fraction = np.clip(((points - start) @ along) / (along @ along), 0.0, 1.0)
    return np.linalg.norm(points - (start + fraction[..., None] * along), axis=-1)


def belief(position, velocity, position_std, velocity_std=0.05):
    cov = np.diag([position_std ** 2] * 2 + [velocity_std ** 2] * 2)
    return AgentBelief(np.array(position, dtype=float), np.array(velocity, dtype=float), cov,
                       EGO_RADIUS)


def swept_paths(rng, ego, velocity, actuation_cov, period=0.1, per_period=5):
    """Sample executed paths over [0, HORIZON]: shape (SAMPLES, steps, 2).

    The model's execution: ``p ~ N(mu, S_p)``, then every control PERIOD the command with an
    error of its own, ``eps_k ~ N(0, S_a)``, held for the period; PER_PERIOD points a period.
    """
    periods = math.ceil(HORIZON / period - 1e-9)
    start = rng.multivariate_normal(ego.position, ego.covariance[:2, :2], SAMPLES)
    noise = rng.multivariate_normal(np.zeros(2), actuation_cov, (SAMPLES, periods))
    times = np.linspace(0.0, periods * period, periods * per_period + 1)
    index = np.minimum((times / period + 1e-9).astype(int), periods - 1)
    # Displacement by the errors: whole periods before, then the current one's share.
    before = np.concatenate([np.zeros((SAMPLES, 1, 2)),
                             np.cumsum(period * noise, axis=1)], axis=1)[:, index]
    within = (times - index * period)[None, :, None] * noise[:, index]
    return start[:, None, :] + times[None, :, None] * velocity + before + within


def avoided(paths, shape, radius):
    """Per sample, whether the path keeps at least RADIUS from SHAPE (segment or centre)."""
    if len(shape) == 2 and np.ndim(shape[0]) == 1:
        distance = point_segment_distance(paths, np.asarray(shape[0]), np.asarray(shape[1]))
    else:
        distance = np.linalg.norm(paths - np.asarray(shape), axis=-1)
    return distance.min(axis=1) >= radius


def encounter(seed):
    """Return a seeded encounter: ego belief, config, StaticObstacles, shapes and radii."""
    rng = np.random.default_rng(seed)
    kind = ('wall', 'end', 'door', 'polygon', 'pillar')[seed % 5]
    distance = rng.uniform(0.9, 2.2)
    thickness = rng.choice([0.0, 0.1])
    segments, centres, radii = [], [], []
    if kind == 'wall':
        angle = rng.uniform(-0.4, 0.4)
        along = np.array([-math.sin(angle), math.cos(angle)])
        middle = np.array([distance, 0.0])
        segments = [[middle - 5.0 * along, middle + 5.0 * along]]
    elif kind == 'end':
        tip = rng.uniform(-0.4, 0.6)
        segments = [[[distance, tip], [distance, tip + 5.0]]]
    elif kind == 'door':
        gap, offset = rng.uniform(0.9, 1.6), rng.uniform(-0.2, 0.2)
        segments = [[[distance, -5.0], [distance, offset - 0.5 * gap]],
                    [[distance, offset + 0.5 * gap], [distance, 5.0]]]
    elif kind == 'polygon':
        side, offset = rng.uniform(0.4, 1.2), rng.uniform(-0.5, 0.5)
        corners = np.array([[distance, offset - side / 2], [distance + side, offset - side / 2],
                            [distance + side, offset + side / 2], [distance, offset + side / 2]])
        segments = [[corners[i], corners[(i + 1) % 4]] for i in range(4)]
    else:
        centres, radii = [[distance + 0.3, rng.uniform(-0.4, 0.4)]], [rng.uniform(0.1, 0.4)]
    half = 0.5 * thickness if kind != 'pillar' else 0.0
    static = obstacles(segments, [half] * len(segments), centres, radii)
    ego = belief([0.0, 0.0], [rng.uniform(0.2, 0.8), rng.uniform(-0.2, 0.2)],
                 rng.uniform(0.03, 0.12))
    actuation_std = rng.uniform(0.03, 0.12)
    config = PlannerConfig(eta=float(rng.choice([0.8, 0.9])), max_speed=1.0,
                           actuation_cov=actuation_std ** 2 * np.eye(2),
                           obstacle_horizon=HORIZON, seed=seed)
    shapes = ([(np.array(segment[0]), np.array(segment[1])) for segment in segments]
              + [np.array(centre) for centre in centres])
    grown = [EGO_RADIUS + half] * len(segments) + [EGO_RADIUS + radius for radius in radii]
    return ego, config, static, shapes, grown, kind


@pytest.mark.parametrize('seed', range(25))
def test_executed_paths_avoid_every_obstacle_with_the_stated_probability(seed):
    ego, config, static, shapes, grown, kind = encounter(seed)
    v_pref = np.array([1.0, 0.0])
    result = plan_velocity(ego, [], v_pref, config, obstacles=static)
    rng = np.random.default_rng(1000 + seed)
    paths = swept_paths(rng, ego, result.velocity, config.actuation_cov)
    stated = result.obstacle_probability
    tolerance = 4.0 * math.sqrt(max(stated * (1.0 - stated), 1e-4) / SAMPLES)
    for shape, radius in zip(shapes, grown, strict=True):
        measured = avoided(paths, shape, radius).mean()
        assert measured >= stated - tolerance, (kind, measured, stated)
    # Started well clear of everything, the plan is certified at eta.
    assert result.feasible and stated >= config.eta, (kind, result)


def test_most_encounters_keep_moving():
    speeds = []
    for seed in range(25):
        ego, config, static, *_ = encounter(seed)
        speeds.append(np.linalg.norm(plan_velocity(ego, [], [1.0, 0.0], config,
                                                   obstacles=static).velocity))
    assert np.median(speeds) > 0.2


def test_speed_towards_a_long_wall_is_the_reflection_principle_bound():
    """The fastest certified speed straight at a long wall, from the first-passage bound.

    The gap ``y`` to the grown wall starts ``N(m0, s0^2)`` and then, the command's error drawn
    every period T, moves as a Brownian motion of variance ``T sigma_a^2`` per second with drift
    ``-a`` (seen at whole periods). Started at time ``-t0 = -s0^2 / (T sigma_a^2)`` from
    ``m0 + a t0``, the reflection principle gives the bound; its largest ``a`` at ``1 - eta``.
    """
    position_std, actuation_std, eta, distance, period = 0.08, 0.1, 0.8, 1.5, 0.1
    ego = belief([0.0, 0.0], [0.5, 0.0], position_std)
    config = PlannerConfig(eta=eta, actuation_cov=actuation_std ** 2 * np.eye(2),
                           obstacle_horizon=HORIZON, control_period=period)
    wall = obstacles([[[distance, -20.0], [distance, 20.0]]])
    result = plan_velocity(ego, [], [1.0, 0.0], config, obstacles=wall)
    mean0 = distance - EGO_RADIUS
    walk = period * actuation_std ** 2
    before = position_std ** 2 / walk
    spread = math.sqrt(position_std ** 2 + walk * HORIZON)

    def failure(speed):
        start = mean0 + speed * before
        reflected = math.exp(2.0 * speed * start / walk + norm.logcdf(
            -(mean0 + speed * (HORIZON + 2.0 * before)) / spread))
        return norm.cdf(-(mean0 - speed * HORIZON) / spread) + reflected - (1.0 - eta)

    expected = brentq(failure, 0.0, mean0 / HORIZON + 1.0, xtol=1e-12)
    assert 0.1 < expected < 0.9
    assert result.velocity == pytest.approx([expected, 0.0], abs=1e-7)
    assert result.obstacle_probability == pytest.approx(eta, abs=1e-6)
    assert result.obstacle_clearance == pytest.approx(mean0)


def test_means_only_model_plans_the_deterministic_wall():
    ego = belief([0.0, 0.0], [0.5, 0.0], 0.1)
    config = PlannerConfig(model='rvo', actuation_cov=0.01 * np.eye(2), obstacle_horizon=HORIZON)
    wall = obstacles([[[1.5, -20.0], [1.5, 20.0]]])
    result = plan_velocity(ego, [], [1.0, 0.0], config, obstacles=wall)
    assert result.velocity == pytest.approx([(1.5 - EGO_RADIUS) / HORIZON, 0.0], abs=1e-7)


def closed_loop(start, goal, static, steps, position_std=0.02, actuation_std=0.02):
    """Noise-free execution of the plans; return the positions (steps + 1, 2)."""
    config = PlannerConfig(actuation_cov=actuation_std ** 2 * np.eye(2), seed=0,
                           obstacle_horizon=HORIZON)
    position, velocity = np.array(start, dtype=float), np.zeros(2)
    positions = [position]
    for _ in range(steps):
        to_goal = np.asarray(goal) - position
        v_pref = to_goal * min(1.0, np.linalg.norm(to_goal)) / max(np.linalg.norm(to_goal),
                                                                   1e-9)
        result = plan_velocity(belief(position, velocity, position_std), [], v_pref, config,
                               obstacles=static)
        velocity = result.velocity
        position = position + 0.1 * velocity
        positions.append(position)
    return np.array(positions)


def test_a_robot_heading_into_a_wall_stops_before_it():
    wall = obstacles([[[1.5, -20.0], [1.5, 20.0]]])
    positions = closed_loop([0.0, 0.0], [4.0, 0.0], wall, 80)
    distance = point_segment_distance(positions, np.array([1.5, -20.0]), np.array([1.5, 20.0]))
    assert distance.min() >= EGO_RADIUS
    # It came close and stopped there.
    assert distance[-1] < EGO_RADIUS + 0.5
    assert np.linalg.norm(positions[-1] - positions[-2]) < 0.01


def test_a_robot_passes_through_a_doorway_wide_enough():
    door = obstacles([[[0.0, -6.0], [0.0, -0.6]], [[0.0, 0.6], [0.0, 6.0]]], [0.05, 0.05])
    positions = closed_loop([-3.0, 0.1], [3.0, 0.0], door, 120)
    for start, end in door.segments:
        distance = point_segment_distance(positions, start, end)
        assert distance.min() >= EGO_RADIUS + 0.05
    assert np.linalg.norm(positions[-1] - [3.0, 0.0]) < 0.2


def test_a_robot_deflects_around_a_pillar():
    pillar = obstacles(centres=[[1.5, 0.05]], radii=[0.3])
    positions = closed_loop([0.0, 0.0], [3.0, 0.0], pillar, 100)
    assert np.linalg.norm(positions - [1.5, 0.05], axis=1).min() >= EGO_RADIUS + 0.3
    assert np.linalg.norm(positions[-1] - [3.0, 0.0]) < 0.2


@pytest.mark.parametrize('seed', range(8))
def test_the_fallback_never_drives_deeper_into_a_wall(seed):
    rng = np.random.default_rng(seed)
    depth = rng.uniform(0.02, 0.2)
    wall = obstacles([[[0.0, -5.0], [0.0, 5.0]], [[-3.0, 1.0], [3.0, 1.0]]])
    position = np.array([-(EGO_RADIUS - depth), rng.uniform(-0.5, 0.5)])
    into = np.array([1.0, rng.uniform(-1.0, 1.0)])
    ego = belief(position, 0.5 * into, 0.05)
    neighbour = belief(position + [-0.8, rng.uniform(-0.3, 0.3)], [0.8, 0.0], 0.05)
    config = PlannerConfig(actuation_cov=0.05 ** 2 * np.eye(2), seed=seed,
                           obstacle_horizon=HORIZON)
    result = plan_velocity(ego, [neighbour], into, config, obstacles=wall)
    path = position + np.linspace(0.0, config.control_period, 51)[:, None] * result.velocity
    for start, end in wall.segments:
        before = point_segment_distance(position, start, end)
        along = point_segment_distance(path, start, end)
        assert along.min() >= min(before, EGO_RADIUS) - 1e-9
    assert not result.feasible


def test_close_to_a_wall_only_velocities_moving_away_are_accepted():
    wall = obstacles([[[0.0, -5.0], [0.0, 5.0]]])
    ego = belief([-EGO_RADIUS - 0.03, 0.0], [0.0, 0.0], 0.05)
    config = PlannerConfig(actuation_cov=0.05 ** 2 * np.eye(2), obstacle_horizon=HORIZON)
    result = plan_velocity(ego, [], [0.3, 1.0], config, obstacles=wall)
    # Away from the wall (-x) with probability eta: -v_x >= Phi^-1(eta) std_a.
    assert -result.velocity[0] >= norm.ppf(config.eta) * 0.05 - 1e-9
    assert result.candidates_feasible > 0


def test_without_obstacles_plans_are_unchanged_bit_for_bit():
    rng = np.random.default_rng(5)
    config = PlannerConfig(actuation_cov=0.01 * np.eye(2), seed=3)
    ego = belief([0.0, 0.0], [0.4, 0.1], 0.05)
    neighbours = [belief(rng.uniform(-3.0, 3.0, 2), rng.uniform(-1.0, 1.0, 2), 0.05)
                  for _ in range(4)]
    plain = plan_velocity(ego, neighbours, [1.0, 0.0], config)
    for static in (None, StaticObstacles.empty()):
        other = plan_velocity(ego, neighbours, [1.0, 0.0], config, obstacles=static)
        assert dataclasses.astuple(other).__repr__() == dataclasses.astuple(plain).__repr__()
    assert (plain.obstacle_clearance, plain.obstacle_probability) == (math.inf, 1.0)


def test_a_team_with_obstacles_plans_as_each_robot_alone():
    rng = np.random.default_rng(2)
    config = PlannerConfig(actuation_cov=0.01 * np.eye(2), seed=1)
    wall = obstacles([[[2.0, -3.0], [2.0, -0.5]], [[2.0, 0.6], [2.0, 3.0]]], [0.05, 0.05])
    egos = [belief(rng.uniform(-1.0, 1.0, 2), rng.uniform(-0.5, 0.5, 2), 0.05)
            for _ in range(4)]
    neighbours = [egos[:i] + egos[i + 1:] for i in range(4)]
    per_robot = [wall, None, wall, obstacles(centres=[[0.0, 2.0]], radii=[0.5])]
    v_prefs = [np.array([1.0, 0.0])] * 4
    team = plan_velocities(egos, neighbours, v_prefs, config, obstacles=per_robot)
    for index in range(4):
        alone = plan_velocity(egos[index], neighbours[index], v_prefs[index], config,
                              obstacles=per_robot[index])
        assert repr(dataclasses.astuple(team[index])) == repr(dataclasses.astuple(alone))


def test_clearance_is_the_distance_from_the_nearest_grown_shape():
    static = obstacles([[[1.0, -1.0], [1.0, 1.0]]], [0.05], [[-2.0, 0.0]], [0.5])
    result = plan_velocity(belief([0.2, 0.3], [0.0, 0.0], 0.05), [], [0.0, 0.0],
                           PlannerConfig(safety_margin=0.1), obstacles=static)
    assert result.obstacle_clearance == pytest.approx(0.8 - EGO_RADIUS - 0.05 - 0.1)


@pytest.mark.parametrize(('call', 'message'), [
    (lambda: plan_velocity(belief([0, 0], [0, 0], 0.1), [], [1, 0], PlannerConfig(),
                           obstacles='wall'), 'obstacles must be StaticObstacles'),
    (lambda: plan_velocity(belief([0, 0], [0, 0], 0.1), [], [1, 0], PlannerConfig(model='mc'),
                           obstacles=obstacles([[[1, 0], [1, 1]]])), "model='mc'"),
    (lambda: PlannerConfig(obstacle_horizon=0.0), 'obstacle_horizon'),
    (lambda: PlannerConfig(obstacle_horizon=math.inf), 'obstacle_horizon'),
    (lambda: obstacles([[[1, 0], [1, 0]]]), 'two equal ends'),
    (lambda: check_parameter('obstacle_horizon', 0.2), 'obstacle_horizon'),
])
def test_bad_inputs_give_one_line_errors(call, message):
    with pytest.raises((ValueError, ParameterError)) as error:
        call()
    assert message in str(error.value)
    assert '\n' not in str(error.value)


@pytest.mark.parametrize('options', [
    {'certificate': 'certified'}, {'model': 'inflate'}, {'model': 'rvo'}, {'method': 'taylor'},
    {'risk': 'joint'}, {'inertia': 0.5, 'passing_bias': 0.1, 'progress_weight': 0.5}])
def test_every_mode_keeps_the_walls(options):
    """Among neighbours, in every planner mode, a feasible plan keeps its obstacle bound."""
    rng = np.random.default_rng(11)
    door = obstacles([[[1.5, -6.0], [1.5, -0.7]], [[1.5, 0.7], [1.5, 6.0]]], [0.05, 0.05])
    config = PlannerConfig(actuation_cov=0.05 ** 2 * np.eye(2), seed=4,
                           obstacle_horizon=HORIZON, **options)
    for _ in range(5):
        ego = belief([0.0, rng.uniform(-0.3, 0.3)], [0.5, 0.0], 0.05)
        neighbours = [belief([rng.uniform(2.0, 4.0), rng.uniform(-2.0, 2.0)], [-0.5, 0.0], 0.05)
                      for _ in range(3)]
        result = plan_velocity(ego, neighbours, [1.0, 0.0], config, obstacles=door,
                               previous=np.array([0.5, 0.0]))
        if result.feasible:
            assert result.obstacle_probability >= config.effective_eta - 1e-9
        path = ego.position + np.linspace(0.0, HORIZON, 41)[:, None] * result.velocity
        for start, end in door.segments:
            assert point_segment_distance(path, start, end).min() >= EGO_RADIUS + 0.05 - 1e-9


def test_acceleration_limits_and_walls_together():
    from prvo_planner.core import VelocityLimits
    wall = obstacles([[[1.0, -5.0], [1.0, 5.0]]])
    ego = belief([0.0, 0.0], [0.8, 0.0], 0.05)
    config = PlannerConfig(actuation_cov=0.05 ** 2 * np.eye(2), obstacle_horizon=HORIZON)
    limits = VelocityLimits(current=np.array([0.8, 0.0]), max_change=0.2)
    result = plan_velocity(ego, [], [1.0, 0.0], config, limits=limits, obstacles=wall)
    assert np.linalg.norm(result.velocity - [0.8, 0.0]) <= 0.2 + 1e-9
    # Braking as hard as allowed: nothing reachable is certified, and nothing moves deeper.
    assert result.velocity[0] <= 0.8 - 0.2 + 1e-6


def test_a_far_end_out_of_reach_constrains_nothing_however_far():
    """The far end of a wall, out of reach, whether its bound is tiny or underflows to 0."""
    config = PlannerConfig(eta=0.95, actuation_cov=0.05 ** 2 * np.eye(2),
                           obstacle_horizon=HORIZON)
    ego = belief([-1.0, 0.0], [0.5, 0.0], 0.02)
    # Past the near end (0, 0.5) of a wall along +y: 3 m long (far end's bound ~1e-200) or
    # 20 m (exactly 0).
    plans = [plan_velocity(ego, [], [1.0, 0.0], config,
                           obstacles=obstacles([[[0.0, 0.5], [0.0, 0.5 + length]]]))
             for length in (3.0, 20.0)]
    assert plans[0].velocity == pytest.approx(plans[1].velocity, abs=1e-12)
    assert plans[0].obstacle_probability == pytest.approx(plans[1].obstacle_probability)
    assert plans[1].velocity[0] > 0.8


@pytest.mark.parametrize('seed', range(24))
def test_approaches_to_doors_keep_clear_of_each_jamb_with_the_stated_probability(seed):
    """The executed motion (own sampler, the model's noise) avoids each jamb segment."""
    ego, config, door, heading, grown, _ = door_approach(seed, HORIZON)
    result = plan_velocity(ego, [], heading, config, obstacles=door)
    rng = np.random.default_rng(2000 + seed)
    paths = swept_paths(rng, ego, result.velocity, config.actuation_cov, config.control_period)
    stated = result.obstacle_probability
    tolerance = 4.0 * math.sqrt(max(stated * (1.0 - stated), 1e-4) / SAMPLES)
    for start, end in door.segments:
        clearance = point_segment_distance(paths, start, end).min(axis=1) - grown
        assert (clearance >= 0.0).mean() >= stated - tolerance, (seed, stated)
    # Clear of the jambs' move-away zone, a feasible plan is certified at eta.
    if result.feasible and not wall_model(door, ego, config).close.any():
        assert stated >= config.eta - 1e-9


def _frame_door(clear_width, depth=0.1, length=4.0):
    """Return a door's two jambs as a map's cells give them: each the four edges of a block."""
    half, thick = 0.5 * clear_width, 0.5 * depth
    segments = []
    for sign in (-1.0, 1.0):
        corners = [[-thick, sign * half], [thick, sign * half], [thick, sign * length],
                   [-thick, sign * length]]
        segments += [[corners[i], corners[(i + 1) % 4]] for i in range(4)]
    return obstacles(segments)


@pytest.mark.parametrize('distance', [2.0, 1.5, 1.0, 0.6, 0.3])
def test_a_robot_heads_straight_through_a_door_it_fits_at_full_speed(distance):
    """Three position stds to spare on each side: no slowing down on the way in (issue 37).

    The jambs' end discs are certified by their tangents parallel to the motion, which the
    straight path keeps its distance to; before, only tangents fixed by the beliefs were
    tried, all slanting towards the path, and the speed fell with the distance to the door.
    The executed motion (own sampler) keeps clear of every jamb segment with the probability
    stated, which is at least eta.
    """
    sigma = 0.05
    door = _frame_door(2.0 * EGO_RADIUS + 6.0 * sigma)
    ego = belief([-distance, 0.0], [1.0, 0.0], sigma, sigma)
    config = PlannerConfig(eta=0.95, actuation_cov=sigma ** 2 * np.eye(2),
                           obstacle_horizon=HORIZON, certificate='certified', seed=1)
    result = plan_velocity(ego, [], np.array([1.0, 0.0]), config, obstacles=door)
    np.testing.assert_allclose(result.velocity, [config.max_speed, 0.0], atol=1e-9)
    assert result.obstacle_probability >= config.eta
    paths = swept_paths(np.random.default_rng(7), ego, result.velocity, config.actuation_cov)
    for start, end in door.segments:
        clear = avoided(paths, (start, end), EGO_RADIUS).mean()
        assert clear >= result.obstacle_probability - 4.0 * math.sqrt(0.05 * 0.95 / SAMPLES)


def test_a_robot_passes_a_pillar_beside_its_way_at_full_speed():
    """A pillar 3 position stds clear of the straight path: certified by the parallel tangent."""
    sigma = 0.05
    pillar = obstacles(centres=[[0.0, EGO_RADIUS + 0.2 + 3.0 * sigma]], radii=[0.2])
    ego = belief([-1.0, 0.0], [1.0, 0.0], sigma, sigma)
    config = PlannerConfig(eta=0.95, actuation_cov=sigma ** 2 * np.eye(2),
                           obstacle_horizon=HORIZON, certificate='certified', seed=1)
    result = plan_velocity(ego, [], np.array([1.0, 0.0]), config, obstacles=pillar)
    np.testing.assert_allclose(result.velocity, [config.max_speed, 0.0], atol=1e-9)
    paths = swept_paths(np.random.default_rng(8), ego, result.velocity, config.actuation_cov)
    clear = avoided(paths, pillar.disc_centres[0], EGO_RADIUS + 0.2).mean()
    assert clear >= result.obstacle_probability >= config.eta
