"""The installed layout is the one 'ros2 run' and ament_index_python expect."""

import importlib.metadata
import os
import pathlib
import xml.etree.ElementTree as ElementTree

from ament_index_python.packages import get_package_prefix, get_package_share_directory
import pytest

PACKAGES = ('prvo_msgs_util', 'prvo_planner', 'prvo_sim')
REPOSITORY = pathlib.Path(__file__).resolve().parents[2]


@pytest.mark.parametrize('package', PACKAGES)
def test_index_marker_and_package_xml(package):
    prefix = pathlib.Path(get_package_prefix(package))
    marker = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / package
    assert marker.is_file(), f'ament index marker missing: {marker}'
    manifest = pathlib.Path(get_package_share_directory(package)) / 'package.xml'
    root = ElementTree.parse(manifest).getroot()
    assert root.get('format') == '3'
    assert root.findtext('name') == package
    assert root.find('export/build_type').text == 'ament_python'


@pytest.mark.parametrize('package', PACKAGES)
def test_every_executable_is_where_ros2_run_looks(package):
    prefix = pathlib.Path(get_package_prefix(package))
    console_scripts = [
        entry_point.name
        for entry_point in importlib.metadata.distribution(package).entry_points
        if entry_point.group == 'console_scripts']
    declared = REPOSITORY / 'src' / package / 'setup.py'
    for name in console_scripts:
        assert f"'{name} = " in declared.read_text(), f'{name} is not declared in {declared}'
        path = prefix / 'lib' / package / name
        assert path.is_file() and os.access(path, os.X_OK), f'{path} is not executable'


def test_installed_package_xml_matches_the_source():
    for package in PACKAGES:
        installed = pathlib.Path(get_package_share_directory(package)) / 'package.xml'
        source = REPOSITORY / 'src' / package / 'package.xml'
        assert installed.read_text() == source.read_text(), f'{installed} is stale'
