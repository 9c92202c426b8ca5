"""QoS profiles, chosen on purpose, one place for every node, the demo and the recorder.

* design: reliable + transient_local + depth 1 ("latched"): a node that starts late (the sync
  node after a restart, the monitor, a recorder) still gets the active design at once.
* ground_speed: the sensor-data profile (best effort, volatile, keep last 5). A late or resent
  speed sample is worse than none (the law integrates distance from receive times and holds the
  last sample), a best-effort subscription also matches a reliable publisher, and a lost sample
  costs one 20-50 ms update. The sync node never waits on a retransmission.
* joint_states, speed_command: reliable, keep last 10 (the monitor computes plant positions
  from them; losing one loses a plant crossing).
* /diagnostics: reliable, keep last 10, as diagnostic_updater publishes it.
"""

from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy,
                       qos_profile_sensor_data)

DESIGN_QOS = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)
GROUND_SPEED_QOS = qos_profile_sensor_data
STATE_QOS = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
DIAGNOSTICS_QOS = STATE_QOS


def deep(profile, depth=100):
    """`profile` with a deeper queue: a recorder rides out a busy second at 100 Hz on it, and
    the offered/requested compatibility (reliability, durability) stays that of `profile`."""
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST,
                      reliability=profile.reliability, durability=profile.durability)
