"""The plan regression tool: a capture compares equal to itself, and a moved plan is named."""

import json
import math

from prvo_planner import plan_regression


def test_a_capture_compares_equal_and_a_moved_plan_is_named(tmp_path, capsys):
    path = tmp_path / 'plans.json'
    assert plan_regression.main(['capture', str(path)]) == 0
    captured = json.loads(path.read_text())
    assert len(captured) == 400
    # Every model, and both feasible plans and fallback plans, are among them.
    assert {plan[-1] == 0 for plan in captured} == {True, False}
    assert plan_regression.main(['compare', str(path)]) == 0
    assert '0 of 400 plans changed' in capsys.readouterr().out
    # One velocity component moved by one unit in the last place.
    captured[17][0] = math.nextafter(captured[17][0], math.inf)
    path.write_text(json.dumps(captured))
    assert plan_regression.main(['compare', str(path)]) == 1
    assert '1 of 400 plans changed: [17]' in capsys.readouterr().out


def test_a_file_that_is_not_a_capture_is_refused_by_name(tmp_path, capsys):
    path = tmp_path / 'other.json'
    path.write_text('[1, 2, 3]')
    assert plan_regression.main(['compare', str(path)]) == 2
    assert f'{path}: not a capture of 400 plans' in capsys.readouterr().err
    path.write_text('not json')
    assert plan_regression.main(['compare', str(path)]) == 2
    assert f'{path}: not a capture' in capsys.readouterr().err
