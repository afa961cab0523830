"""Install prvo_sim, an ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'prvo_sim'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/scenarios', glob('scenarios/*.yaml')),
        ('share/' + package_name + '/scenarios/maps', glob('scenarios/maps/*')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
        ('share/' + package_name + '/rviz', glob('rviz/*.rviz')),
    ],
    install_requires=['setuptools', 'rosbags'],
    zip_safe=True,
    maintainer='prvo maintainers',
    maintainer_email='maintainers@prvo.dev',
    description='Noisy kinematic multi-robot simulator and launch-free scenario runner for PRVO.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'sim = prvo_sim.sim_main:main',
            'run_scenario = prvo_sim.run_scenario:main',
            'prvo-run = prvo_sim.run_scenario:main',
            'experiments = prvo_sim.bench.experiments:main',
            'nav2_stand_in = prvo_sim.upstream_node:main',
            'planner_server_stand_in = prvo_sim.planned_path_node:main',
        ],
    },
)
