"""
Launch the live digital twin on a ROS 2 install: one or more actuators, each in its namespace.

Usage (after ``colcon build`` and sourcing the workspace)::

    ros2 launch wet_eha_thermal eha_twin.launch.py stage:=3
    ros2 launch wet_eha_thermal eha_twin.launch.py actuators:=left,right view:=true
    ros2 launch wet_eha_thermal eha_twin.launch.py actuators_file:=rigs.yaml sim_rigs:=false
    ros2 launch wet_eha_thermal eha_twin.launch.py record_output:=runs/test honour_limit:=true
    ros2 launch wet_eha_thermal eha_twin.launch.py sim_rigs:=false managed:=true

Per actuator (a namespace: ``eha`` by default, whose topics are the twin's
/eha ones) it starts the simulated rig (``sim_rigs``), the estimator and the
recorder (``record``), all in that namespace; with ``view`` each estimator
serves its Foxglove view, the first on ``foxglove_port``, the next actuator's
on the next port. What starts, with which parameters, remappings and ports,
is decided by :func:`wet_eha_thermal.launch_plan.plan_from_arguments` (tested
there); the arguments and the actuators file are described in
``docs/live.md`` ("Several actuators").

``launch`` and ``launch_ros`` are not on PyPI, so they are imported inside
:func:`generate_launch_description` only: the file stays importable (and
style-checked) where they are missing.
"""

#: Launch argument -> (default, description)
ARGUMENTS = {
    'actuators': ('eha', 'namespaces of the actuators, comma separated (e.g. left,right)'),
    'actuators_file': ('', 'YAML list of actuators with their own files (replaces actuators)'),
    'sim_rigs': ('true', 'start a simulated rig per actuator (false: real rigs publish)'),
    'record': ('true', 'start a recorder per actuator'),
    'view': ('false', "serve each estimator's Foxglove view, one port per actuator"),
    'foxglove_port': ('8765', "port of the first actuator's Foxglove view"),
    'stage': ('6', 'reference stage of the simulated rigs (1-6)'),
    'duty_file': ('', 'duty CSV for the simulated rigs (empty: use the stage)'),
    'use_sim_time': ('false', 'follow /clock instead of the system clock'),
    'executor': ('events', 'rclpy executor of rigs and estimators: events or single'),
    'honour_limit': ('false', "the rigs' drives honour the estimators' current limits"),
    'record_output': ('', 'bag directory (one per actuator below it when several; empty: '
                          'runs/eha_<UTC time>)'),
    'managed': ('false', 'estimators as lifecycle nodes, unconfigured until configured and '
                         'activated (ros2 lifecycle set, or a lifecycle manager)'),
}


def generate_launch_description():
    """Return the launch description: the arguments, then the planned nodes."""
    from ament_index_python.packages import get_package_share_directory
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node
    from wet_eha_thermal.launch_plan import PACKAGE, plan_from_arguments

    def nodes(context):
        args = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
        return [Node(package=PACKAGE, executable=n.executable, name=n.name,
                     namespace=n.namespace, output='screen', arguments=n.arguments,
                     parameters=n.parameters, remappings=n.remappings)
                for n in plan_from_arguments(args, get_package_share_directory(PACKAGE))]

    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=text)
         for name, (default, text) in ARGUMENTS.items()] + [OpaqueFunction(function=nodes)])
