from setuptools import find_packages, setup

package_name = 'pppbot_eval'

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
    description='Headless scenarios against ground truth: metrics, reports, the evaluation node, `pppbot eval`.',
    license='Apache-2.0',
    entry_points={
        # `pppbot eval`: found by pppbot_bringup.cli (a module with add_arguments and main).
        'pppbot.verbs': ['eval = pppbot_eval.ros.cli'],
    },
)
