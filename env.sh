# Source this file (". env.sh") to use prvo by hand: it activates .venv/ and puts the venv on
# AMENT_PREFIX_PATH so that ament_index_python (and 'ros2 run', where installed) find the
# prvo packages and their executables under .venv/lib/<package>/.
_prvo_root=$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")" && pwd)
if [ ! -f "$_prvo_root/.venv/.prvo-setup-stamp" ]; then
  echo "env.sh: prvo is not set up yet: run '$_prvo_root/run.sh setup' first, then source this again" >&2
  unset _prvo_root
  return 1 2>/dev/null || exit 1
fi
# shellcheck source=/dev/null
VIRTUAL_ENV_DISABLE_PROMPT=${VIRTUAL_ENV_DISABLE_PROMPT:-} . "$_prvo_root/.venv/bin/activate"
case ":${AMENT_PREFIX_PATH:-}:" in
  *":$_prvo_root/.venv:"*) ;;
  *) export AMENT_PREFIX_PATH="$_prvo_root/.venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}" ;;
esac
export RMW_IMPLEMENTATION=${RMW_IMPLEMENTATION:-rmw_fastrtps_cpp}
# One BLAS thread per process: a team runs a planner per robot, and idle BLAS threads spinning
# on a few cores cost more than the small products they would speed up.
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}
# Fast DDS over UDP on loopback: its shared-memory transport can keep a restarted process (a
# simulator started again) from hearing the nodes that outlived the old one.
export FASTDDS_BUILTIN_TRANSPORTS=${FASTDDS_BUILTIN_TRANSPORTS:-UDPv4}
unset _prvo_root
