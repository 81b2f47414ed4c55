import os

from setuptools import find_packages, setup

package_name = 'pppbot_sim'


def tree(source, target):
    """data_files entries that install the folder ``source`` (and subfolders) under ``target``."""
    entries = []
    for folder, _, files in os.walk(source):
        if files:
            entries.append((os.path.join(target, os.path.relpath(folder, source)),
                            [os.path.join(folder, f) for f in files]))
    return entries


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        *tree('../worlds', 'share/' + package_name + '/worlds'),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='pppbot developers',
    maintainer_email='dev@pppbot.dev',
    description=('MuJoCo simulator node for ppp_bot: Gazebo-style SDF worlds, spawning, lidar, '
                 'IMU, clock, ground-truth maps.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'simulator = pppbot_sim.ros.simulator:main',
            'ground_truth_map = pppbot_sim.ground_truth_cli:main',
        ],
    },
)
