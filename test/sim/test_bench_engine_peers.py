"""The engine benchmark's circles and its peer table, on a team of two, peers absent or faked."""

import itertools
import json
import math
import sys
import types

import numpy as np
import pytest

from prvo_sim.bench import engine as bench_engine
from prvo_sim.bench import walls as bench_walls

PEER_MODULES = ('irsim', 'irsim.lib', 'irsim.lib.algorithm', 'irsim.lib.algorithm.rvo', 'pyrvo',
                'navground', 'navground.core', 'navground.sim')
HEADERS = ('robots', 'radius m', 'ir-sim RVO ms', 'RVO2 ORCA ms', 'navground ORCA ms',
           'navground HRVO ms', 'navground HL ms', 'PRVO plan ms', 'PRVO step ms',
           'PRVO plan / ir-sim', 'PRVO step / ir-sim')


def without_peers(monkeypatch):
    """Make every peer's package fail to import, as where none is installed."""
    for name in PEER_MODULES:
        # None in sys.modules: `import name` raises ImportError.
        monkeypatch.setitem(sys.modules, name, None)


def table_lines(text, first_header):
    """Return the lines of the Markdown table of TEXT whose header starts with FIRST_HEADER."""
    lines = text.splitlines()
    start = next(index for index, line in enumerate(lines)
                 if line.startswith(f'| {first_header} |'))
    end = next((index for index in range(start, len(lines)) if not lines[index].startswith('|')),
               len(lines))
    return lines[start:end]


def cells(line):
    return [cell.strip() for cell in line.strip('|').split('|')]


def test_circles_grow_with_the_team_and_start_apart():
    radii = {count: bench_engine.circle_radius_of(count) for count in (2, 8, 16, 48, 100, 200)}
    assert radii == {2: 4.0, 8: 4.0, 16: 4.0, 48: 6.0, 100: 12.5, 200: 25.0}
    for count in (8, 16, 48, 100, 200):
        document = bench_engine.engine_circle_document(count)
        starts = np.array([robot['start'] for robot in document['robots']])
        assert np.allclose(np.linalg.norm(starts, axis=1), radii[count], atol=1e-3)
        gaps = min(math.dist(first, second) for first, second in itertools.combinations(
            starts, 2)) - 2.0 * document['robots'][0]['radius']
        # From 32 robots on, 2 pi / 8 m of arc apart: 0.185 m between the robots' edges.
        assert gaps > 0.18
        assert document['noise']['position_std'] == 0.05
    quiet = bench_engine.engine_circle_document(10, noise=False)['noise']
    assert set(quiet.values()) == {0.0}


def test_absent_peers_are_skipped_with_a_note_and_prvo_still_measured(tmp_path, monkeypatch,
                                                                      capsys):
    without_peers(monkeypatch)
    json_path = tmp_path / 'engine.json'
    assert bench_engine.main(['--robots', '--peer-robots', '2', '--out', str(tmp_path),
                              '--json', str(json_path)]) == 0
    out = capsys.readouterr().out
    for peer, package in bench_engine.PEER_PACKAGES.items():
        assert f'note: {peer}: {package} is not importable here, skipped' in out
    timed = table_lines(out, 'robots')
    assert tuple(cells(timed[0])) == HEADERS
    row = dict(zip(HEADERS, cells(timed[2]), strict=True))
    assert row['robots'] == '2' and row['radius m'] == '4.0'
    for header in HEADERS[2:7] + HEADERS[9:]:
        assert row[header] == 'n/a'
    results = json.loads(json_path.read_text())
    assert results['teams'] == [] and len(results['notes']) == len(bench_engine.PEERS)
    (peer,) = results['peers']
    assert peer['irsim_rvo_ms_mean'] is None and peer['navground_hl_arrived'] is None
    assert peer['prvo_plan_ms_mean'] > 0.0 and peer['prvo_plan_ms_median'] > 0.0
    # The plan is timed within the step (both rounded to the microsecond).
    assert peer['prvo_step_ms_mean'] >= peer['prvo_plan_ms_mean'] - 1e-3
    assert peer['prvo_arrived'] == 2 and peer['prvo_collisions'] == 0
    assert row['PRVO plan ms'] == (f"{peer['prvo_plan_ms_mean']:.3f} / "
                                   f"{peer['prvo_plan_ms_median']:.3f}")


def test_a_present_peer_fills_its_cells_and_the_ratios(tmp_path, monkeypatch):
    without_peers(monkeypatch)
    # ir-sim and navground "installed": their runs are stand-ins with known times.
    for name in ('irsim', 'navground'):
        monkeypatch.setitem(sys.modules, name, types.ModuleType(name))
    monkeypatch.setattr(bench_engine, 'time_peer',
                        lambda count, dt: (np.array([1.0, 3.0, 2.0, 2.0]), count - 1))
    ran = []

    def peer_trajectory(peer, world):
        ran.append(peer)
        positions = np.array([world.starts, world.goals])
        return np.array([0.0, 0.1]), positions, np.array([0.1, 0.2, 0.6])
    monkeypatch.setattr(bench_walls, 'peer_trajectory', peer_trajectory)
    notes = []
    peers = bench_walls.importable_peers(bench_engine.PEERS, notes, bench_engine.PEER_PACKAGES)
    assert peers == ['irsim-rvo', 'navground-orca', 'navground-hrvo', 'navground-hl']
    assert notes == ['rvo2-orca: pyrvo is not importable here, skipped']
    row = bench_engine.peer_row(2, tmp_path, peers)
    assert ran == ['navground-orca', 'navground-hrvo', 'navground-hl']
    assert (row['irsim_rvo_ms_mean'], row['irsim_rvo_ms_median'], row['irsim_rvo_arrived']) \
        == (2.0, 2.0, 1)
    assert (row['navground_hrvo_ms_mean'], row['navground_hrvo_ms_median']) == (0.3, 0.2)
    assert row['navground_orca_arrived'] == 2 and row['rvo2_orca_ms_mean'] is None
    for kind in ('plan', 'step'):
        for summary in ('mean', 'median'):
            assert row[f'prvo_{kind}_over_irsim_{summary}'] == pytest.approx(
                row[f'prvo_{kind}_ms_{summary}'] / 2.0, abs=0.006)
    text = bench_engine.peer_table([row])
    arrivals = table_lines(text.split('Robots at their goals')[1], 'robots')
    assert cells(arrivals[2]) == ['2', '1/2', 'n/a', '2/2', '2/2', '2/2', '2/2', '0']


def test_progress_is_printed_every_ten_simulated_seconds(tmp_path, capsys):
    scenario = bench_engine.write_scenario(bench_engine.engine_circle_document(2),
                                           tmp_path / 'circle2.yaml')
    progress = bench_engine.Progress(scenario)
    team = types.SimpleNamespace(world=types.SimpleNamespace(contact_count=0))
    goals = np.array([robot.goal for robot in scenario.robots])
    for time in np.arange(0.0, 25.0, 0.1):
        states = np.zeros((2, 4))
        states[0, :2] = goals[0] if time > 15.0 else 0.0
        progress(team, types.SimpleNamespace(time=float(time), states=states))
    lines = [line for line in capsys.readouterr().out.splitlines() if 'simulated' in line]
    assert [line.split(',')[0].strip() for line in lines] == [
        '2 robots: 10.0 s simulated', '2 robots: 20.0 s simulated']
    assert '0 at their goals' in lines[0] and '1 at their goals' in lines[1]
