"""The experiments' methods table: its certificate rows and the scenario copies they run."""

import yaml

from prvo_sim.bench import experiments
from prvo_sim.scenario import find_scenario, load_scenario


def test_a_scenario_copy_changes_only_the_bound_of_its_planners(tmp_path):
    shipped = find_scenario('mixed12')
    copy = experiments.scenario_with_certificate(shipped, 'certified', tmp_path)
    assert copy.name == 'mixed12.yaml' and copy.parent == tmp_path
    original, changed = (yaml.safe_load(path.read_text()) for path in (shipped, copy))
    assert changed['planner'] == {**original['planner'], 'certificate': 'certified'}
    assert {key: value for key, value in changed.items() if key != 'planner'} == {
        key: value for key, value in original.items() if key != 'planner'}
    for robot in load_scenario(copy).robots:
        assert robot.planner['certificate'] == 'certified'


def test_the_certificate_rows_are_cantelli_at_08_and_certified_at_four_etas():
    rows = [(method, eta, certificate)
            for _, method, eta, certificate in experiments.CERTIFICATE_VARIANTS]
    assert rows == [('prvo', 0.8, 'cantelli'), ('prvo', 0.8, 'certified'),
                    ('prvo', 0.9, 'certified'), ('prvo', 0.95, 'certified'),
                    ('prvo', 0.99, 'certified')]
    # The paper's rows keep the paper's bound whatever the planner's default.
    assert all(certificate == 'cantelli' for _, method, _, certificate
               in experiments.METHOD_VARIANTS if method.startswith('prvo'))


def test_methods_only_without_runs_is_refused(tmp_path, capsys):
    assert experiments.main(['--methods-only', '--skip-runs', '--out', str(tmp_path)]) == 2
    assert 'leave nothing to do' in capsys.readouterr().err
