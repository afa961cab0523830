"""
Do code changes move any plan? 400 seeded plans of the core, captured and compared.

    python -m prvo_planner.plan_regression capture PATH   # before a change
    python -m prvo_planner.plan_regression compare PATH   # after it

The plans cover every model (prvo, rvo, inflate, mc), method (exact, taylor), risk (pairwise,
joint), time horizon (2 s, 5 s, none), 16 and 64 directions, 0 to 8 neighbours with random full
covariances and radii, inertia, passing bias, the receding gate on and off, and a previous
command or none. Each plan is kept as its velocity, feasibility, achieved ``k``, Cantelli bound,
number of constraints and number of feasible candidates; JSON keeps every float exactly.
A plan is unchanged when its velocity is within ``VELOCITY_TOLERANCE`` per component, its
achieved ``k`` and bound within ``MARGIN_TOLERANCE`` (or equal, as infinities), and its
feasibility and counts equal: floating-point rounding (a compiled kernel, another order of
summation) moves plans by far less. A change meant to speed the planner up must leave all 400
unchanged; a change of the fallback only moves plans without a feasible candidate
(``candidates_feasible == 0``).

Exit codes: 0 captured, or no plan changed; 1 some plan changed; 2 bad input.
"""

import argparse
import json
import math
import pathlib
import sys

import numpy as np

from prvo_planner.core import AgentBelief, PlannerConfig, plan_velocity

PLAN_COUNT = 400
SEED = 20261129
VELOCITY_TOLERANCE = 1e-9  # m/s
MARGIN_TOLERANCE = 1e-9


def _belief(rng, centre, spread):
    """Return a belief near CENTRE with a random full covariance of scale SPREAD."""
    factor = rng.normal(size=(4, 4)) * spread
    covariance = factor @ factor.T + 1e-4 * np.eye(4)
    return AgentBelief(centre + rng.normal(size=2), rng.normal(size=2) * 0.7, covariance,
                       float(rng.uniform(0.2, 0.5)))


def cases(count=PLAN_COUNT, seed=SEED):
    """Yield COUNT seeded (ego, neighbours, v_pref, config, previous) plan inputs."""
    rng = np.random.default_rng(seed)
    for index in range(count):
        neighbour_count = int(rng.integers(0, 9))
        ego = _belief(rng, np.zeros(2), float(rng.uniform(0.0, 0.15)))
        neighbours = [_belief(rng, rng.uniform(-5, 5, size=2), float(rng.uniform(0.0, 0.15)))
                      for _ in range(neighbour_count)]
        # Overlapping neighbours are a different question (the fallback's): kept apart here.
        neighbours = [neighbour for neighbour in neighbours
                      if np.linalg.norm(neighbour.position - ego.position)
                      > neighbour.radius + ego.radius]
        model = ['prvo', 'rvo', 'inflate', 'mc'][index % 4] if index % 10 else 'prvo'
        config = PlannerConfig(
            eta=float(rng.uniform(0.5, 0.95)), max_speed=float(rng.uniform(0.5, 1.5)),
            num_directions=int(rng.choice([16, 64])),
            time_horizon=float(rng.choice([2.0, 5.0, np.inf])),
            actuation_cov=float(rng.uniform(0, 0.01)) * np.eye(2),
            method=['exact', 'taylor'][index % 2], model=model,
            risk=['pairwise', 'joint'][(index // 2) % 2], mc_samples=200, seed=index,
            inertia=float(rng.choice([0.0, 0.5])), passing_bias=float(rng.choice([0.0, 0.1])),
            receding_gate=bool(index % 7),
            # The paper's bound: the plans these cases were captured with.
            certificate='cantelli')
        previous = rng.normal(size=2) * 0.5 if index % 3 else None
        yield ego, neighbours, rng.normal(size=2), config, previous


def plans(count=PLAN_COUNT, seed=SEED):
    """Return every plan of ``cases`` as a list of plain values, one list per plan."""
    results = []
    for ego, neighbours, v_pref, config, previous in cases(count, seed):
        result = plan_velocity(ego, neighbours, v_pref, config, previous=previous)
        results.append([*result.velocity.tolist(), result.feasible, result.achieved_k,
                        result.eta_bound, result.num_constraints, result.candidates_feasible])
    return results


def _close(before, after, tolerance):
    return before == after or math.isclose(before, after, rel_tol=0.0, abs_tol=tolerance)


def same_plan(before, after):
    """Whether two plans of ``plans`` agree within the stated tolerances."""
    x_before, y_before, feasible_before, k_before, bound_before, *counts_before = before
    x_after, y_after, feasible_after, k_after, bound_after, *counts_after = after
    return (_close(x_before, x_after, VELOCITY_TOLERANCE)
            and _close(y_before, y_after, VELOCITY_TOLERANCE)
            and feasible_before == feasible_after
            and _close(k_before, k_after, MARGIN_TOLERANCE)
            and _close(bound_before, bound_after, MARGIN_TOLERANCE)
            and counts_before == counts_after)


def changed_plans(old, new):
    """Return the indices of the plans that differ between OLD and NEW (same length)."""
    return [index for index, (before, after) in enumerate(zip(old, new, strict=True))
            if not same_plan(before, after)]


def build_parser():
    """Return the command-line parser."""
    parser = argparse.ArgumentParser(
        prog='plan_regression',
        description='Capture 400 seeded plans of the core, or compare them with a capture.')
    parser.add_argument('mode', choices=('capture', 'compare'))
    parser.add_argument('path', type=pathlib.Path, help='the capture (JSON)')
    return parser


def main(argv=None):
    """Run the command line; return the exit code."""
    options = build_parser().parse_args(sys.argv[1:] if argv is None else argv)
    if options.mode == 'capture':
        options.path.write_text(json.dumps(plans()) + '\n')
        print(f'captured {PLAN_COUNT} plans in {options.path}')
        return 0
    try:
        old = json.loads(options.path.read_text())
    except (OSError, ValueError) as error:
        print(f'plan_regression: error: {options.path}: not a capture ({error})',
              file=sys.stderr)
        return 2
    if not isinstance(old, list) or len(old) != PLAN_COUNT:
        print(f'plan_regression: error: {options.path}: not a capture of {PLAN_COUNT} plans',
              file=sys.stderr)
        return 2
    changed = changed_plans(old, plans())
    without_feasible = [index for index in changed if old[index][-1] == 0]
    print(f'{len(changed)} of {PLAN_COUNT} plans changed'
          + (f': {changed} ({len(without_feasible)} of them had no feasible candidate)'
             if changed else ''))
    return 1 if changed else 0


if __name__ == '__main__':
    sys.exit(main())
