"""The user's contract in one place: topic names, message types, joint names and units.

Standard message types only (no custom interfaces package). Every node and the recorder take
names from here, so a rename is one edit. Default namespace: /planter (topics are relative).
"""

NAMESPACE = 'planter'

# geometry_msgs/TwistStamped, input: twist.linear.x = measured ground speed (m/s, forward > 0)
GROUND_SPEED = 'ground_speed'
# std_msgs/String, latched (reliable, transient_local, depth 1): JSON of the active design in SI
# units; keys at least `mechanism` (five_bar | three_arm), `plants_per_revolution` (1 | 3),
# `plant_spacing` (m), `planting_depth` (m), then the mechanism's own fields.
DESIGN = 'design'
# sensor_msgs/JointState from drive feedback: name = [MECHANISM_JOINT[mechanism]],
# position = mechanism shaft angle (rad, unwrapped, increasing forward), velocity (rad/s)
JOINT_STATES = 'joint_states'
# std_msgs/Float64: commanded mechanism shaft speed (rad/s) sent to the drive
SPEED_COMMAND = 'speed_command'
# per-plant predictions and the rolling uprightness rate (monitor; see README for the fields)
PLANTS = 'plants'
UPRIGHTNESS_RATE = 'uprightness_rate'
# diagnostic_msgs/DiagnosticArray, absolute name as diagnostic_aggregator expects
DIAGNOSTICS = '/diagnostics'

MECHANISM_JOINT = {'five_bar': 'sun_bar', 'three_arm': 'carrier'}
PLANTS_PER_REVOLUTION = {'five_bar': 1, 'three_arm': 3}
