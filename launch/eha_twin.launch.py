"""
Launch the live digital twin on a ROS 2 install: the simulated rig, the estimator, the recorder.

Usage (after ``colcon build`` and sourcing the workspace)::

    ros2 launch wet_eha_thermal eha_twin.launch.py stage:=3
    ros2 launch wet_eha_thermal eha_twin.launch.py use_sim_time:=true
    ros2 launch wet_eha_thermal eha_twin.launch.py record_output:=runs/test
    ros2 launch wet_eha_thermal eha_twin.launch.py stage:=1 honour_limit:=true

Every node reads ``config/estimator.params.yaml`` from the package's share
directory: its ``/**`` keys apply to every node, so the rig and the recorder
take the same ``config_file``, ``qos`` and ``topic_prefix`` as the estimator
and ignore the keys they do not declare; the recorder also stores that file
in the recording (``params_file``). Launch arguments: ``stage`` (1-6, the
rig's duty), ``duty_file`` (a duty CSV; empty: the stage), ``use_sim_time``
(every node follows /clock), ``executor`` (events or single; the recorder
always uses events), ``record`` (true: start the recorder) and
``record_output`` (its bag directory, or one MCAP file for a name ending
``.mcap``; empty: ``runs/eha_<UTC time>`` in the working folder) and
``honour_limit`` (true: the rig's drive honours the estimator's current
limit, as ``live --closed-loop``).

``launch`` and ``launch_ros`` are not on PyPI, so they are imported inside
:func:`generate_launch_description` only: the file stays importable (and
style-checked) where they are missing.
"""

import os


def generate_launch_description():
    """Return the launch description of the rig, the estimator and the recorder nodes."""
    from ament_index_python.packages import get_package_share_directory
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument
    from launch.conditions import IfCondition
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node
    from launch_ros.parameter_descriptions import ParameterValue

    share = get_package_share_directory('wet_eha_thermal')
    params_file = os.path.join(share, 'config', 'estimator.params.yaml')
    stage = LaunchConfiguration('stage')
    duty_file = LaunchConfiguration('duty_file')
    use_sim_time = LaunchConfiguration('use_sim_time')
    executor = LaunchConfiguration('executor')
    sim_time = ParameterValue(use_sim_time, value_type=bool)
    return LaunchDescription([
        DeclareLaunchArgument('stage', default_value='6',
                              description='reference stage of the simulated rig (1-6)'),
        DeclareLaunchArgument('duty_file', default_value='',
                              description='duty CSV for the rig (empty: use the stage)'),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='follow /clock instead of the system clock'),
        DeclareLaunchArgument('executor', default_value='events',
                              description='rclpy executor of rig and estimator: events or single'),
        DeclareLaunchArgument('honour_limit', default_value='false',
                              description="the rig's drive honours the estimator's current "
                                          'limit (a closed loop)'),
        DeclareLaunchArgument('record', default_value='true',
                              description='record every topic of the twin to a rosbag2 bag'),
        DeclareLaunchArgument('record_output', default_value='',
                              description='bag directory of the recording, or one file for a '
                                          'name ending .mcap (empty: runs/eha_<UTC time>)'),
        Node(package='wet_eha_thermal', executable='wet-eha-thermal-rig', name='eha_sim_rig',
             output='screen', arguments=['--executor', executor],
             parameters=[params_file,
                         {'stage': ParameterValue(stage, value_type=int),
                          'duty_file': ParameterValue(duty_file, value_type=str),
                          'honour_limit': ParameterValue(LaunchConfiguration('honour_limit'),
                                                         value_type=bool),
                          'use_sim_time': sim_time}]),
        Node(package='wet_eha_thermal', executable='wet-eha-thermal-estimator',
             name='eha_thermal_estimator', output='screen',
             arguments=['--executor', executor],
             parameters=[params_file, {'use_sim_time': sim_time}]),
        Node(package='wet_eha_thermal', executable='wet-eha-thermal-record', name='eha_recorder',
             output='screen', arguments=['--executor', 'events'],
             condition=IfCondition(LaunchConfiguration('record')),
             parameters=[params_file,
                         {'params_file': params_file, 'qos_depth': 1000,
                          'output': ParameterValue(LaunchConfiguration('record_output'),
                                                   value_type=str),
                          'use_sim_time': sim_time}]),
    ])
