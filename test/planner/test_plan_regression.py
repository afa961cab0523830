"""The plan regression tool: a capture compares equal to itself, and a moved plan is named.

Plans agree within 1e-9 m/s per velocity component and 1e-9 in the achieved k and its bound, with
the same feasibility and counts: rounding moves none, a real change is named.
"""

import json
import math

from prvo_planner import plan_regression


def planned_once(plans):
    """Return PLANS (a function) that plans on its first call and returns that list after."""
    kept = []

    def once():
        if not kept:
            kept.append(plans())
        return kept[0]

    return once


def test_a_capture_compares_equal_and_a_moved_plan_is_named(tmp_path, capsys, monkeypatch):
    path = tmp_path / 'plans.json'
    assert plan_regression.main(['capture', str(path)]) == 0
    captured = json.loads(path.read_text())
    assert len(captured) == 400
    # Every model, and both feasible plans and fallback plans, are among them.
    assert {plan[-1] == 0 for plan in captured} == {True, False}
    # Planned again, the same 400 plans; what follows checks the comparison, so the plans of
    # this compare are kept for the next two, not planned twice more.
    monkeypatch.setattr(plan_regression, 'plans', planned_once(plan_regression.plans))
    assert plan_regression.main(['compare', str(path)]) == 0
    assert '0 of 400 plans changed' in capsys.readouterr().out
    # Rounding: one velocity component moved by one unit in the last place, another and a
    # finite achieved k by less than the tolerance.
    finite = next(index for index, plan in enumerate(captured) if math.isfinite(plan[3]))
    captured[17][0] = math.nextafter(captured[17][0], math.inf)
    captured[18][1] += 0.9e-9
    captured[finite][3] -= 0.9e-9
    path.write_text(json.dumps(captured))
    assert plan_regression.main(['compare', str(path)]) == 0
    capsys.readouterr()
    # A velocity moved by more than the tolerance, a feasibility flipped, a count changed.
    captured[20][1] += 2e-9
    captured[21][2] = not captured[21][2]
    captured[22][-1] += 1
    path.write_text(json.dumps(captured))
    assert plan_regression.main(['compare', str(path)]) == 1
    assert '3 of 400 plans changed: [20, 21, 22]' in capsys.readouterr().out


def test_a_file_that_is_not_a_capture_is_refused_by_name(tmp_path, capsys):
    path = tmp_path / 'other.json'
    path.write_text('[1, 2, 3]')
    assert plan_regression.main(['compare', str(path)]) == 2
    assert f'{path}: not a capture of 400 plans' in capsys.readouterr().err
    path.write_text('not json')
    assert plan_regression.main(['compare', str(path)]) == 2
    assert f'{path}: not a capture' in capsys.readouterr().err
