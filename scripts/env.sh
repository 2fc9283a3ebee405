# Sourced by every script of ours: keep DDS on loopback and use the project's venv.
# (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST: discovery never leaves this machine; checked with a capture.)
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_STATIC_PEERS ROS_LOCALHOST_ONLY
export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-42}"
export RMW_IMPLEMENTATION="${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}"
export PYTHONUNBUFFERED=1
_AXIS_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export PATH="$_AXIS_ROOT/.venv/bin:$PATH"
