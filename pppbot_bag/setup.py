from setuptools import find_packages, setup

package_name = 'pppbot_bag'

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
    description='rosbag2 (MCAP) bags without rosbag2: core, record and play nodes, `pppbot bag`.',
    license='Apache-2.0',
    entry_points={
        # `pppbot bag`: found by pppbot_bringup.cli (a module with add_arguments and main).
        'pppbot.verbs': ['bag = pppbot_bag.cli'],
    },
)
