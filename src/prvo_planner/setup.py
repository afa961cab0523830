"""Install prvo_planner, an ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'prvo_planner'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='prvo maintainers',
    maintainer_email='maintainers@prvo.dev',
    description='Per-robot PRVO velocity planner node and its numpy core.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'planner = prvo_planner.planner_node:main',
            'bench = prvo_planner.bench:main',
        ],
    },
)
