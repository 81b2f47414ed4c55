from glob import glob

from setuptools import find_packages, setup

package_name = 'pppbot_description'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/urdf', glob('urdf/*.xacro')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='pppbot developers',
    maintainer_email='dev@pppbot.dev',
    description='ppp_bot robot description (modular xacro) and a robot_state_publisher node.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'robot_state_publisher = pppbot_description.ros.robot_state_publisher:main',
        ],
        # The simulator's process runs it beside the simulator (launch_sim's use_composition).
        'pppbot_sim.hosted_nodes': [
            'robot_state_publisher = pppbot_description.ros.robot_state_publisher:RobotStatePublisher',
        ],
    },
)
