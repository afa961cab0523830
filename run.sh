#!/usr/bin/env bash
# prvo's one entry point: sets up .venv/ (idempotent, quick when nothing changed), then runs a job.
#
#   ./run.sh demo [run_scenario options]   set up, then run the default scenario (circle8)
#   ./run.sh test [pytest options]         set up, then lint and run the whole test suite
#   ./run.sh setup                         only set up
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
VENV="$ROOT/.venv"
STAMP="$VENV/.prvo-setup-stamp"
PACKAGES=(prvo_msgs_util prvo_planner prvo_sim)

die() {
  echo "prvo setup: error: $*" >&2
  exit 1
}

find_python() {
  local candidate
  for candidate in ${PYTHON:-} python3 python3.13 python3.12 python3.11 python3.10; do
    if command -v "$candidate" >/dev/null 2>&1 \
      && "$candidate" -c 'import sys; sys.exit(sys.version_info < (3, 10))' 2>/dev/null; then
      echo "$candidate"
      return
    fi
  done
  die "no Python >= 3.10 found (tried ${PYTHON:-} python3 python3.13 ... python3.10);" \
    "install one, e.g. 'sudo apt-get install python3 python3-venv'"
}

# A fingerprint of everything the venv is built from: the pins, the packages' sources and this file.
fingerprint() {
  (
    cd "$ROOT"
    find requirements.txt run.sh "${PACKAGES[@]/#/src/}" -type f \
      -not -path '*/__pycache__/*' -not -path '*.egg-info/*' -not -path '*/build/*' \
      -not -name '*.pyc' -print0 | sort -z | xargs -0 sha256sum | sha256sum | cut -d' ' -f1
  )
}

pip_install() {
  local what=$1
  shift
  local log="$VENV/pip-last.log"
  if ! "$VENV/bin/python" -m pip install --disable-pip-version-check --no-input "$@" >"$log" 2>&1; then
    grep -E '^(ERROR|error)|Could not|No matching|Failed|NewConnectionError|Temporary failure' \
      "$log" | head -n 15 >&2 || tail -n 15 "$log" >&2
    die "pip could not install $what (full log: $log); check the network connection to the" \
      "Python package index and the messages above"
  fi
}

# Executables where 'ros2 run' looks for them: <prefix>/lib/<package>/<executable>. pip ignores
# setup.cfg's install_scripts, so each console script in .venv/bin is linked there.
link_ros2_run_executables() {
  "$VENV/bin/python" - "$VENV" "${PACKAGES[@]}" <<'PY'
import importlib.metadata as metadata
import os
import sys

venv, packages = sys.argv[1], sys.argv[2:]
for package in packages:
    lib_dir = os.path.join(venv, 'lib', package)
    os.makedirs(lib_dir, exist_ok=True)
    for stale in os.listdir(lib_dir):
        os.remove(os.path.join(lib_dir, stale))
    for entry_point in metadata.distribution(package).entry_points:
        if entry_point.group != 'console_scripts':
            continue
        script = os.path.join(venv, 'bin', entry_point.name)
        if not os.path.isfile(script):
            sys.exit(f'console script {script} of {package} is missing after install')
        os.symlink(os.path.relpath(script, lib_dir), os.path.join(lib_dir, entry_point.name))
PY
}

setup() {
  local python wanted
  python=$(find_python)
  wanted=$(fingerprint)
  if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$wanted" ] && [ -x "$VENV/bin/python" ]; then
    return
  fi
  rm -f "$STAMP"
  if [ ! -x "$VENV/bin/python" ]; then
    echo "prvo setup: creating $VENV with $python ($("$python" --version 2>&1))"
    "$python" -m venv "$VENV" 2>/dev/null || {
      rm -rf "$VENV"
      die "'$python -m venv' failed: the venv module or ensurepip is missing; on Debian/Ubuntu" \
        "install it with 'sudo apt-get install python3-venv' and run this again"
    }
  fi
  local requirements_hash
  requirements_hash=$(sha256sum "$ROOT/requirements.txt" | cut -d' ' -f1)
  if [ ! -f "$VENV/.requirements-stamp" ] || \
    [ "$(cat "$VENV/.requirements-stamp")" != "$requirements_hash" ]; then
    echo 'prvo setup: installing pinned dependencies (ROS 2 Jazzy wheels, numpy, scipy, ...)'
    pip_install 'the pinned dependencies in requirements.txt' -r "$ROOT/requirements.txt"
    echo "$requirements_hash" >"$VENV/.requirements-stamp"
  fi
  echo "prvo setup: installing ${PACKAGES[*]} from src/"
  # Not editable: an editable install skips data_files (the ament index marker, package.xml).
  pip_install "${PACKAGES[*]}" --no-deps --no-build-isolation --force-reinstall \
    "${PACKAGES[@]/#/$ROOT/src/}"
  local package
  for package in "${PACKAGES[@]}"; do
    # pip builds in the source tree; its leftovers are not sources.
    rm -rf "$ROOT/src/$package/build" "$ROOT/src/$package/$package.egg-info"
  done
  link_ros2_run_executables || die 'could not link the executables under .venv/lib/<package>/'
  # The ray search, the moments, the certificate, the walls' bounds and the choice are compiled by
  # numba on their first import; compiled here once, into the installed package's __pycache__, every
  # planner process after this only loads them.
  echo 'prvo setup: compiling the ray search, the moments, the certificate, the walls and the choice (numba, once per install, about 20 s)'
  "$VENV/bin/python" -I -c 'import prvo_planner.core.ray_search, prvo_planner.core.moment_kernels, prvo_planner.core.certificate_kernels, prvo_planner.core.wall_kernels, prvo_planner.core.choice_kernels' \
    || die 'could not compile the ray search, the moments, the certificate, the walls and the' \
      'choice (prvo_planner.core.ray_search, prvo_planner.core.moment_kernels,' \
      'prvo_planner.core.certificate_kernels, prvo_planner.core.wall_kernels,' \
      'prvo_planner.core.choice_kernels) with numba'
  echo "$wanted" >"$STAMP"
  echo 'prvo setup: done'
}

job=${1:-}
[ $# -gt 0 ] && shift
case "$job" in
  setup)
    setup
    ;;
  demo)
    setup
    # shellcheck source=env.sh
    source "$ROOT/env.sh"
    exec python -m prvo_sim.run_scenario "$ROOT/src/prvo_sim/scenarios/circle8.yaml" \
      --out "$ROOT/results/circle8" "$@"
    ;;
  test)
    setup
    # shellcheck source=env.sh
    source "$ROOT/env.sh"
    cd "$ROOT"
    echo 'prvo test: lint (ruff, ament style)'
    ruff check .
    echo 'prvo test: pytest'
    status=0
    # Two workers, one a core (a test's time goes mostly to starting ROS processes, which is
    # CPU); a worker that runs out of tests takes some of the other's (worksteal), so the long
    # tests do not queue on one. --durations=25 ends the report with the slowest tests. The
    # caller's options come after these and win: './run.sh test -n 0' runs in this one process.
    python -m pytest -n 2 --dist worksteal --durations=25 "$@" || status=$?
    if [ "$status" -eq 5 ]; then
      echo 'prvo test: error: pytest collected no tests' >&2
    fi
    exit "$status"
    ;;
  *)
    echo "usage: $0 {demo|test|setup} [options]" >&2
    exit 2
    ;;
esac
