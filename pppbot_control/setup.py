from setuptools import find_packages, setup

package_name = 'pppbot_control'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='pppbot developers',
    maintainer_email='dev@pppbot.dev',
    description=('Differential-drive controller, twist_mux and keyboard teleop for ppp_bot, with '
                 'a ROS-free kinematics and odometry core.'),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'diff_drive_controller = pppbot_control.ros.diff_drive_controller:main',
            'twist_mux = pppbot_control.ros.twist_mux:main',
            'teleop_keyboard = pppbot_control.ros.teleop_keyboard:main',
            'joy_node = pppbot_control.ros.joy_node:main',
            'teleop_node = pppbot_control.ros.teleop_joy:main',
        ],
        # The controllers the simulator hosts in its process, by ros2_control type (pppbot_sim.hosting).
        'pppbot_sim.hosted_controllers': [
            'diff_drive_controller/DiffDriveController = pppbot_control.ros.hosting:diff_drive_controller',
        ],
        'pppbot_sim.controller_managers': [
            'controller_manager = pppbot_control.ros.hosting:controller_manager',
        ],
        # Nodes the simulator's process runs beside it (launch_sim's use_composition).
        'pppbot_sim.hosted_nodes': [
            'twist_mux = pppbot_control.ros.twist_mux:TwistMuxNode',
        ],
    },
)
