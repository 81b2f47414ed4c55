from setuptools import find_packages, setup

package_name = 'pppbot_lockstep'

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
    description=("How pppbot's nodes run: the node runner, the node base class and its step port, lockstep's "
                 "protocol, participant and coordinator."),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [],
    },
)
