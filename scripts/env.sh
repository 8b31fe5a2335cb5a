# Source this file in your shell after scripts/demo or scripts/test has built once:
#   source scripts/env.sh
# It sources the workspace's devel/setup.bash so rosrun, roslaunch and rostest
# find slope_monitor. The workspace is $SLOPE_MONITOR_WS (default under ~/.cache).
_sm_lib="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/lib.sh"
. "$_sm_lib"
if [ -f "$SM_WS/devel/setup.bash" ]; then
  . "$SM_WS/devel/setup.bash"
  echo "[slope_monitor] using workspace $SM_WS"
else
  echo "[slope_monitor] no built workspace at $SM_WS: run scripts/demo or scripts/test first" >&2
fi
unset _sm_lib
