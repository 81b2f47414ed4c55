from glob import glob

from setuptools import find_packages, setup

package_name = 'pppbot_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('../config/*.yaml') + glob('../config/*.rviz')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='pppbot developers',
    maintainer_email='dev@pppbot.dev',
    description='pppbot bringup (launch_sim), process supervisor and the pppbot command line.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'pppbot = pppbot_bringup.cli:main',
            'launch_sim = pppbot_bringup.ros.launch_sim:main',
        ],
        # `pppbot <verb>`: found by pppbot_bringup.cli (a module with add_arguments and main).
        'pppbot.verbs': [
            'run = pppbot_bringup.run',
            'topic = pppbot_bringup.ros.topic',
            'teleop = pppbot_bringup.teleop',
            'launch_sim = pppbot_bringup.ros.launch_sim',
        ],
    },
)
