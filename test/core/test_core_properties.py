"""Property-based tests: any valid input gives a finite velocity within the speed limit."""

import math

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
import numpy as np

from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity

finite = st.floats(-20.0, 20.0, allow_nan=False, allow_infinity=False)
vectors = st.tuples(finite, finite)


@st.composite
def covariances(draw):
    """Random PSD 4x4 matrices, including singular ones (rank 0 to 4)."""
    rank = draw(st.integers(0, 4))
    entries = draw(st.lists(st.floats(-1.0, 1.0), min_size=4 * rank, max_size=4 * rank))
    factor = np.array(entries, dtype=float).reshape(4, rank)
    return factor @ factor.T


@st.composite
def beliefs(draw):
    return AgentBelief(draw(vectors), draw(st.tuples(st.floats(-3, 3), st.floats(-3, 3))),
                       draw(covariances()), draw(st.floats(0.05, 1.0)))


@st.composite
def configs(draw):
    model = draw(st.sampled_from(['prvo', 'rvo', 'inflate', 'mc']))
    return PlannerConfig(
        eta=draw(st.floats(0.05, 0.99)),
        k=draw(st.none() | st.floats(0.0, 10.0)),
        max_speed=draw(st.floats(0.05, 3.0)),
        num_directions=draw(st.integers(1, 40)),
        time_horizon=draw(st.sampled_from([math.inf, 0.5, 3.0, 10.0])),
        neighbor_distance=draw(st.sampled_from([math.inf, 1.0, 10.0])),
        actuation_cov=np.diag(draw(st.tuples(st.floats(0.0, 0.1), st.floats(0.0, 0.1)))),
        safety_margin=draw(st.floats(0.0, 0.5)),
        method=draw(st.sampled_from(['exact', 'taylor'])),
        model=model,
        receding_gate=draw(st.booleans()),
        risk=draw(st.sampled_from(['pairwise', 'joint'])),
        mc_samples=draw(st.integers(1, 50)),
        seed=draw(st.none() | st.integers(0, 2 ** 32 - 1)),
    )


@settings(deadline=None, max_examples=500, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(ego=beliefs(), neighbours=st.lists(beliefs(), max_size=6), v_pref=vectors,
       config=configs())
def test_plan_is_finite_and_within_the_speed_limit(ego, neighbours, v_pref, config):
    result = plan_velocity(ego, neighbours, v_pref, config)
    assert result.velocity.shape == (2,)
    assert np.all(np.isfinite(result.velocity))
    assert np.hypot(*result.velocity) <= config.max_speed * (1.0 + 1e-12)
    assert not math.isnan(result.achieved_k)
    assert 0.0 <= result.eta_bound <= 1.0
    assert 0 <= result.num_constraints <= len(neighbours)
    assert isinstance(result.feasible, bool)
