from setuptools import find_packages, setup

package_name = 'pppbot_viz'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['page.html']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='pppbot developers',
    maintainer_email='dev@pppbot.dev',
    description='The live view (rerun: viz node, web page with goal and pose tools) and the Foxglove bridge.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'viz = pppbot_viz.ros.viz:main',
            'foxglove_bridge = pppbot_viz.ros.foxglove_bridge:main',
        ],
        # `pppbot foxglove`, `pppbot view`: found by pppbot_bringup.cli (modules with add_arguments and main).
        'pppbot.verbs': ['foxglove = pppbot_viz.ros.foxglove_cli', 'view = pppbot_viz.ros.view_cli'],
    },
)
