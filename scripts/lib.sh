# Shared helpers for scripts/demo, scripts/test, scripts/build and scripts/env.sh.
# Sourced, not run. Sets SM_SRC (the package source) and SM_WS (the catkin
# workspace, outside the source tree; choose it with SLOPE_MONITOR_WS).

SM_SRC="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ -z "${SLOPE_MONITOR_WS:-}" ]; then
  _sm_hash="$(printf '%s' "$SM_SRC" | md5sum | cut -c1-8)"
  SM_WS="${XDG_CACHE_HOME:-$HOME/.cache}/slope_monitor/ws_$(basename "$SM_SRC")_${_sm_hash}"
else
  SM_WS="$SLOPE_MONITOR_WS"
fi
# ROS's Python tools run under the system interpreter.
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"
# The master and the nodes of a demo, replay or test bind and advertise
# loopback only unless the caller chose an address (doc/security.md: ROS 1
# has no authentication; scripts/check_listeners shows what listens).
export ROS_IP="${ROS_IP:-127.0.0.1}"
export ROS_HOSTNAME="${ROS_HOSTNAME:-127.0.0.1}"

sm_say() { printf '[slope_monitor] %s\n' "$*" >&2; }
sm_die() { printf '[slope_monitor] ERROR: %s\n' "$*" >&2; exit 1; }

# Install every Debian package of a list that is missing (default
# scripts/debian-packages.txt; scripts/debian-packages-rviz.txt for rviz).
sm_install_missing() {
  local list="${1:-$SM_SRC/scripts/debian-packages.txt}" missing=() p
  [ -f "$list" ] || sm_die "package list $list not found"
  while read -r p; do
    p="${p%%#*}"; p="$(echo "$p" | xargs)"
    [ -n "$p" ] || continue
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
  done < "$list"
  [ ${#missing[@]} -eq 0 ] && { sm_say "all Debian packages present"; return 0; }
  sm_say "installing missing Debian packages: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || sm_die "not root and no sudo: install these packages first: ${missing[*]}"
    sudo="sudo"
  fi
  $sudo apt-get update -qq || sm_die "apt-get update failed"
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q --no-install-recommends "${missing[@]}" \
    || sm_die "apt-get install failed for: ${missing[*]}"
}

# Create (or reuse) the workspace with the package linked into src/.
sm_workspace() {
  mkdir -p "$SM_WS/src" || sm_die "cannot create workspace $SM_WS"
  local link="$SM_WS/src/slope_monitor"
  if [ -L "$link" ] && [ "$(readlink "$link")" != "$SM_SRC" ]; then
    sm_say "workspace linked to another source tree; relinking to $SM_SRC"
    rm -f "$link"
  fi
  [ -e "$link" ] || ln -s "$SM_SRC" "$link" || sm_die "cannot link $SM_SRC into $SM_WS/src"
  [ -f "$SM_WS/src/CMakeLists.txt" ] || ln -sf /usr/share/catkin/cmake/toplevel.cmake "$SM_WS/src/CMakeLists.txt"
  sm_say "workspace: $SM_WS (set SLOPE_MONITOR_WS to choose another)"
}

# Build the package (and its tests when $1 = tests) with Ninja: it compiles a
# target's objects as soon as the headers they need exist, not after every
# library they link to, so both cores stay busy through the whole build
# (doc/testing.md). A workspace configured with make before is reconfigured.
sm_build() {
  sm_workspace
  local jobs="${SM_JOBS:-$(nproc)}"
  if [ -f "$SM_WS/build/CMakeCache.txt" ] && ! grep -q '^CMAKE_GENERATOR:INTERNAL=Ninja$' "$SM_WS/build/CMakeCache.txt"; then
    sm_say "workspace $SM_WS was configured for make; reconfiguring it for Ninja (a full rebuild)"
    rm -rf "$SM_WS/build" "$SM_WS/devel"
  fi
  # ccache (scripts/debian-packages.txt, SM_CCACHE=1) keeps every object it
  # compiled, so a fresh clone on a machine that built before recompiles only
  # what changed. Off by default: on a new machine every file is a miss, and
  # a miss costs ~0.8 s of CPU per file (preprocessing for the hash, hashing
  # the precompiled header), ~3.5 CPU-minutes of a cold build (doc/testing.md).
  local cache=()
  if [ "${SM_CCACHE:-0}" = 1 ] && [ -z "${CMAKE_CXX_COMPILER_LAUNCHER:-}" ] && command -v ccache >/dev/null; then
    cache=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
    # The message headers are generated seconds before they are compiled;
    # pch_defines and time_macros let ccache cache files that start from a
    # precompiled header (CMakeLists.txt, SM_PCH).
    export CCACHE_SLOPPINESS="${CCACHE_SLOPPINESS:-include_file_mtime,include_file_ctime,time_macros,pch_defines}"
  elif [ -z "${CMAKE_CXX_COMPILER_LAUNCHER:-}" ]; then
    cache=(-DCMAKE_CXX_COMPILER_LAUNCHER= -DCMAKE_C_COMPILER_LAUNCHER=)  # a workspace that had it drops it
  fi
  # "sm_build demo": only what the replay graph and the demo tools need (the
  # benchmarks and the other offline tools wait for scripts/test);
  # "sm_build tests": everything and the tests in one go; "sm_build configure":
  # only CMake (scripts/test then builds and runs the tests in one Ninja run).
  local targets=()
  if [ "${1:-}" = demo ]; then
    targets=(slope_monitor_nodelets make_survey_bag deformation_summary process_bag)
  elif [ "${1:-}" = tests ]; then
    targets=(all tests)
  elif [ "${1:-}" = configure ]; then
    targets=(clean_test_results)
  fi
  if [ "${1:-}" = configure ]; then
    sm_say "configuring with catkin_make --use-ninja (Release${SM_CCACHE:+, SM_CCACHE=$SM_CCACHE})"
  else
    sm_say "building with catkin_make --use-ninja (-j$jobs, Release${SM_CCACHE:+, SM_CCACHE=$SM_CCACHE})"
  fi
  # devel's Python folder exists before CMake runs: catkin writes the test
  # environment (build/catkin_generated/setup_cached.sh, which every run_tests
  # target sources) with only the folders that exist then, and without this
  # one the rostests' rosservice / rostopic cannot load our message types.
  mkdir -p "$SM_WS/devel/lib/python3/dist-packages"
  (cd "$SM_WS" && catkin_make --use-ninja -DCMAKE_BUILD_TYPE=Release -DCATKIN_ENABLE_TESTING=ON "${cache[@]}" \
     -j"$jobs" "${targets[@]}" >"$SM_WS/build.log" 2>&1) || {
    tail -n 60 "$SM_WS/build.log" >&2
    sm_die "build failed; full log: $SM_WS/build.log"
  }
  [ "${1:-}" = configure ] && sm_say "configured" || sm_say "build ok"
}

# Build single targets of an already configured workspace: sm_build_targets T1 [T2 ...]
sm_build_targets() {
  cmake --build "$SM_WS/build" -j "${SM_JOBS:-$(nproc)}" --target "$@" >>"$SM_WS/build.log" 2>&1
}

sm_source_ws() {
  [ -f "$SM_WS/devel/setup.bash" ] || sm_die "no built workspace at $SM_WS: run scripts/demo or scripts/test first"
  # catkin's setup puts devel's Python folder on PYTHONPATH only if it exists
  # when sourced; on a new workspace genpy writes our message modules there
  # later in the same build, and rosservice / rostopic must find them.
  mkdir -p "$SM_WS/devel/lib/python3/dist-packages"
  # shellcheck disable=SC1091
  set +u; source "$SM_WS/devel/setup.bash"; set -u
}

# --help or -h as the first argument of a script that sources this file: its
# header comment (the lines after the #! line up to the first line that is not
# a comment), exit 0, nothing installed, built or written (issue 38). Only for
# the scripts in this folder ($0), never for a shell that sources lib.sh.
if [ "$(cd "$(dirname "$0")" 2>/dev/null && pwd)" = "$SM_SRC/scripts" ]; then
  case "${1:-}" in
    -h | --help)
      sed -n '2,/^[^#]/s/^# \{0,1\}//p' "$0"
      exit 0
      ;;
  esac
fi
