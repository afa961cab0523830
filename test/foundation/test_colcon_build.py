"""The colcon workspace under ros2_ws/ builds all three packages and makes them findable."""

import os
import pathlib
import shutil
import subprocess

REPOSITORY = pathlib.Path(__file__).resolve().parents[2]
PACKAGES = ('prvo_msgs_util', 'prvo_planner', 'prvo_sim')


def test_colcon_build_of_ros2_ws(tmp_path):
    colcon = shutil.which('colcon')
    assert colcon, 'colcon is not installed in the environment (requirements.txt pins it)'
    build = subprocess.run(
        [colcon, '--log-base', str(tmp_path / 'log'), 'build',
         '--build-base', str(tmp_path / 'build'), '--install-base', str(tmp_path / 'install')],
        cwd=REPOSITORY / 'ros2_ws', capture_output=True, text=True, timeout=300)
    assert build.returncode == 0, build.stdout + build.stderr
    assert '3 packages finished' in build.stdout, build.stdout

    # A shell that knows nothing of the venv's prefix must find the packages after sourcing.
    environment = {key: value for key, value in os.environ.items()
                   if key not in ('AMENT_PREFIX_PATH', 'COLCON_PREFIX_PATH')}
    query = ('from ament_index_python.packages import get_package_prefix; '
             f'print(*(get_package_prefix(p) for p in {PACKAGES!r}))')
    found = subprocess.run(
        ['bash', '-c', f'source "{tmp_path}/install/setup.bash" && python -c "{query}"'],
        env=environment, capture_output=True, text=True, timeout=60)
    assert found.returncode == 0, found.stderr
    prefixes = found.stdout.split()
    assert prefixes == [str(tmp_path / 'install' / package) for package in PACKAGES]
    for package, executable in (('prvo_planner', 'planner'), ('prvo_sim', 'sim'),
                                ('prvo_sim', 'run_scenario')):
        path = tmp_path / 'install' / package / 'lib' / package / executable
        assert os.access(path, os.X_OK), f'{path} is not executable'
    scenarios = tmp_path / 'install' / 'prvo_sim' / 'share' / 'prvo_sim' / 'scenarios'
    assert (scenarios / 'circle8.yaml').is_file()
    share = scenarios.parent
    assert (share / 'launch' / 'scenario.launch.py').is_file()
    assert (share / 'rviz' / 'prvo.rviz').is_file()
    # colcon builds out of tree: nothing may be left in the sources.
    assert not list((REPOSITORY / 'src').glob('*/build'))
