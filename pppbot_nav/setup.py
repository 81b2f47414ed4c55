from setuptools import find_packages, setup

package_name = 'pppbot_nav'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['behavior_trees/*.xml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='pppbot developers',
    maintainer_email='dev@pppbot.dev',
    description="Map server, map saver, AMCL, costmaps, planner, controller and navigator for ppp_bot (Nav2's role).",
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'map_saver = pppbot_nav.ros.map_saver:main',
            'map_saver_cli = pppbot_nav.ros.map_saver_cli:cli_main',
            'map_server = pppbot_nav.ros.map_server:main',
            'amcl = pppbot_nav.ros.amcl:main',
            'planner_server = pppbot_nav.ros.planner_server:main',
            'controller_server = pppbot_nav.ros.controller_server:main',
            'bt_navigator = pppbot_nav.ros.navigator:main',
            'behavior_server = pppbot_nav.ros.behavior_server:main',
            'smoother_server = pppbot_nav.ros.smoother_server:main',
            'waypoint_follower = pppbot_nav.ros.waypoint_follower:main',
            'velocity_smoother = pppbot_nav.ros.velocity_smoother:main',
            'collision_monitor = pppbot_nav.ros.collision_monitor:main',
            'navigation = pppbot_nav.ros.navigation:main',
            'localization = pppbot_nav.ros.localization:main',
            'lifecycle_manager = pppbot_nav.ros.lifecycle_manager:main',
            'costmap_filter_info_server = pppbot_nav.ros.costmap_filter_info_server:main',
            'costmap_filters = pppbot_nav.ros.costmap_filters:main',
        ],
        # Nav2's plugins by type name (pluginlib's role: pppbot_nav.plugins); a user's package
        # registers its own in the same groups.
        'pppbot_nav.planners': [
            'nav2_navfn_planner::NavfnPlanner = pppbot_nav.planner.plugin_settings:NavfnParameters',
            'nav2_smac_planner::SmacPlanner2D = pppbot_nav.planner.plugin_settings:Smac2DParameters',
            'pppbot_nav::GridAStar = pppbot_nav.planner.plugin_settings:GridAStarParameters',
        ],
        'pppbot_nav.controllers': [
            'dwb_core::DWBLocalPlanner = pppbot_nav.controller.plugin_settings:DWBParameters',
            'nav2_regulated_pure_pursuit_controller::RegulatedPurePursuitController = '
            'pppbot_nav.controller.plugin_settings:RegulatedPurePursuitParameters',
        ],
        'pppbot_nav.dwb_critics': [
            'dwb_critics::RotateToGoalCritic = pppbot_nav.controller.dwb_critic_plugins:RotateToGoalParameters',
            'dwb_critics::OscillationCritic = pppbot_nav.controller.dwb_critic_plugins:OscillationParameters',
            'dwb_critics::BaseObstacleCritic = pppbot_nav.controller.dwb_critic_plugins:BaseObstacleParameters',
            'dwb_critics::ObstacleFootprintCritic = '
            'pppbot_nav.controller.dwb_critic_plugins:ObstacleFootprintParameters',
            'dwb_critics::GoalAlignCritic = pppbot_nav.controller.dwb_critic_plugins:GoalAlignParameters',
            'dwb_critics::PathAlignCritic = pppbot_nav.controller.dwb_critic_plugins:PathAlignParameters',
            'dwb_critics::PathDistCritic = pppbot_nav.controller.dwb_critic_plugins:PathDistParameters',
            'dwb_critics::GoalDistCritic = pppbot_nav.controller.dwb_critic_plugins:GoalDistParameters',
            'dwb_critics::PreferForwardCritic = pppbot_nav.controller.dwb_critic_plugins:PreferForwardParameters',
            'dwb_critics::TwirlingCritic = pppbot_nav.controller.dwb_critic_plugins:TwirlingParameters',
        ],
        'pppbot_nav.goal_checkers': [
            'nav2_controller::SimpleGoalChecker = pppbot_nav.controller.plugin_settings:SimpleGoalCheckerParameters',
            'nav2_controller::StoppedGoalChecker = pppbot_nav.controller.plugin_settings:StoppedGoalCheckerParameters',
            'nav2_controller::PositionGoalChecker = '
            'pppbot_nav.controller.plugin_settings:PositionGoalCheckerParameters',
        ],
        'pppbot_nav.progress_checkers': [
            'nav2_controller::SimpleProgressChecker = '
            'pppbot_nav.controller.plugin_settings:SimpleProgressCheckerParameters',
            'nav2_controller::PoseProgressChecker = '
            'pppbot_nav.controller.plugin_settings:PoseProgressCheckerParameters',
        ],
        'pppbot_nav.costmap_layers': [
            'nav2_costmap_2d::StaticLayer = pppbot_nav.costmap.layer_settings:StaticLayerParameters',
            'nav2_costmap_2d::ObstacleLayer = pppbot_nav.costmap.layer_settings:ObstacleLayerParameters',
            'nav2_costmap_2d::VoxelLayer = pppbot_nav.costmap.layer_settings:VoxelLayerParameters',
            'nav2_costmap_2d::InflationLayer = pppbot_nav.costmap.layer_settings:InflationLayerParameters',
        ],
        'pppbot_nav.costmap_filters': [
            'nav2_costmap_2d::KeepoutFilter = pppbot_nav.costmap.filters:KeepoutFilterParameters',
            'nav2_costmap_2d::SpeedFilter = pppbot_nav.costmap.filters:SpeedFilterParameters',
        ],
        'pppbot_nav.smoothers': [
            'nav2_smoother::SimpleSmoother = pppbot_nav.planner.simple_smoother:SimpleSmootherParameters',
        ],
        'pppbot_nav.behaviors': [
            'nav2_behaviors::Spin = pppbot_nav.ros.behavior_plugins:SpinPlugin',
            'nav2_behaviors::BackUp = pppbot_nav.ros.behavior_plugins:BackUpPlugin',
            'nav2_behaviors::DriveOnHeading = pppbot_nav.ros.behavior_plugins:DriveOnHeadingPlugin',
            'nav2_behaviors::Wait = pppbot_nav.ros.behavior_plugins:WaitPlugin',
            'nav2_behaviors::AssistedTeleop = pppbot_nav.ros.behavior_plugins:AssistedTeleopPlugin',
        ],
        # `pppbot <verb>`: found by pppbot_bringup.cli (a module with add_arguments and main).
        'pppbot.verbs': [
            'nav = pppbot_nav.ros.nav_cli',
            'map_saver = pppbot_nav.ros.map_saver_cli',
        ],
    },
)
