"""
The twin's interface, without ROS: topic names, message types, estimates, thermocouples.

Inputs (what the rig publishes; SI units, as the messages define them):

| input | default topic | type | unit |
| --- | --- | --- | --- |
| phase current | /eha/current | std_msgs/Float64 | A RMS |
| motor speed | /eha/speed | std_msgs/Float64 | rad/s (signed) |
| port A pressure | /eha/pressure_a | sensor_msgs/FluidPressure | Pa absolute |
| port B pressure | /eha/pressure_b | sensor_msgs/FluidPressure | Pa absolute |
| accumulator pressure | /eha/pressure_acc | sensor_msgs/FluidPressure | Pa absolute |
| or: differential pressure | /eha/pressure_diff | sensor_msgs/FluidPressure | Pa, p_A - p_B |
| actuator position (LVDT) | /eha/position | std_msgs/Float64 | m |
| ambient temperature | /eha/ambient | sensor_msgs/Temperature | degC |
| thermocouples | /eha/measured/<name> | sensor_msgs/Temperature | degC |

A Float64 carries no stamp: its sample time is the receiving node's clock (the
ROS clock, so /clock under use_sim_time). Messages with a header use its stamp,
or the clock when the stamp is zero.

Outputs of the estimator: /eha/estimate/<name> (sensor_msgs/Temperature, degC,
variance = uncertainty^2) for every name in ``ESTIMATES``; /eha/state
(std_msgs/Float64MultiArray: the model's state vector in K) with the name of
each element on /eha/state_names (std_msgs/String holding JSON, transient-local:
the names do not change within a run); /diagnostics
(diagnostic_msgs/DiagnosticArray, 1 Hz); /eha/alerts (std_msgs/String holding
JSON, transient-local so a late subscriber gets the last one); acknowledgements
on /eha/alerts/ack (std_msgs/String: a quantity, or empty for all).

The estimator, the offline tools and the ROS nodes take these names from
here; :mod:`.ros.topics` adds what needs rclpy (QoS profiles, publishing).
"""

PREFIX = '/eha'
#: The nodes' names (one place: ``live`` and the rig's ``wait_for`` name them too)
ESTIMATOR_NODE, RIG_NODE, RECORDER_NODE = 'eha_thermal_estimator', 'eha_sim_rig', 'eha_recorder'
INPUT_TOPICS = {
    'current_A': f'{PREFIX}/current',
    'speed_rad_s': f'{PREFIX}/speed',
    'p_a_Pa': f'{PREFIX}/pressure_a',
    'p_b_Pa': f'{PREFIX}/pressure_b',
    'p_acc_Pa': f'{PREFIX}/pressure_acc',
    'dp_Pa': f'{PREFIX}/pressure_diff',      # instead of the three above (pressure_inputs)
    'position_m': f'{PREFIX}/position',
}
# sensor_msgs/FluidPressure; the others are std_msgs/Float64
PRESSURE_INPUTS = ('p_a_Pa', 'p_b_Pa', 'p_acc_Pa', 'dp_Pa')
#: message type name of every input, as bags store it
INPUT_TYPES = {name: ('sensor_msgs/msg/FluidPressure' if name in PRESSURE_INPUTS
                      else 'std_msgs/msg/Float64') for name in INPUT_TOPICS}
AMBIENT_TOPIC = f'{PREFIX}/ambient'
MEASURED_PREFIX = f'{PREFIX}/measured'
ESTIMATE_PREFIX = f'{PREFIX}/estimate'
STATE_TOPIC = f'{PREFIX}/state'
#: latched std_msgs/String JSON {"unit": "K", "names": [...]}: one name per element of
#: the state (the model's :attr:`~wet_eha_thermal.model.eha.EHAModel.quantities`)
STATE_NAMES_TOPIC = f'{PREFIX}/state_names'
ALERT_TOPIC = f'{PREFIX}/alerts'
ACK_TOPIC = f'{PREFIX}/alerts/ack'
#: latched std_msgs/String JSON of each node that is ready ({"node", "ready", ...}); the
#: simulated rig starts its duty once the nodes it waits for are, and says so here too
READY_TOPIC = f'{PREFIX}/ready'
DIAGNOSTICS_TOPIC = '/diagnostics'
ESTIMATES = ('winding_mean', 'winding_hotspot', 'frame', 'magnet', 'airgap_oil_outlet',
             'motor_oil_outlet', 'pump_case', 'pump_outlet', 'chamber_a', 'chamber_b',
             'accumulator', 'oil')
#: thermocouples of the reference rig (docs/model.md) and the estimate each one measures
#: (an output of :mod:`wet_eha_thermal.model.quantities`)
THERMOCOUPLES = {'winding': 'winding_mean', 'frame': 'frame', 'pump_inlet': 'pump_outlet',
                 'pump_case': 'pump_case', 'chamber_a': 'chamber_a', 'chamber_b': 'chamber_b',
                 'motor_oil_outlet': 'motor_oil_outlet'}


def prefixed(topic: str, prefix: str) -> str:
    """Return ``topic`` (one of this module's, under ``/eha``) moved under ``prefix``."""
    if not topic.startswith(PREFIX):
        return topic
    return prefix.rstrip('/') + topic[len(PREFIX):]
