#!/usr/bin/env bash
# gyro_emulator developer entry point: sets up .venv (idempotent) and runs a job.
#
#   ./dev.sh main   set everything up, then run the main job (the paper-validation demo)
#   ./dev.sh test   set everything up, then run the full test suite (lint + unit + ROS integration;
#                   three workers, GYRO_TEST_WORKERS=N to change; arguments go to pytest)
#   ./dev.sh setup  only set up .venv
#   ./dev.sh shell  a bash shell with the venv and ROS environment active
#
# ./dev.sh shell reads your ~/.bashrc first and activates the venv after it, so a
# pyenv, conda or ROS setup there cannot put another Python ahead of the venv's.
# In it, `gyro-emulator ros --help` lists the stand-ins for the ros2 CLI (not on
# PyPI); `colcon build` then `. install/setup.sh` (colcon-core's hook;
# install/setup.bash would need the colcon-bash extension, which is not pinned)
# puts the package where `ros2 run` looks.
#
# Works on a fresh Debian 12 with Python 3.11 and no ROS: everything comes from PyPI.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
ROOT=$(pwd)
VENV="$ROOT/.venv"

pick_python() {
    for cand in "${PYTHON:-}" python3.11 python3; do
        [ -n "$cand" ] || continue
        if command -v "$cand" >/dev/null 2>&1 &&
            "$cand" -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' 2>/dev/null; then
            echo "$cand"; return 0
        fi
    done
    echo "dev.sh: Python 3.11 is required (the ROS 2 Jazzy wheels are pinned for it)." >&2
    echo "        On Debian 12: apt-get install python3 python3-venv" >&2
    return 1
}

warm_cache() {
    # Compile the sensor kernel into numba's cache now, so the first node start
    # (gyro-emulator-node from the venv; ./dev.sh main and the tests from the
    # source tree) only loads it. The cache is keyed to each copy's path, hence
    # both copies, side by side; a failure only means the first start compiles.
    echo "dev.sh: compiling the sensor kernel into numba's cache (once per install)" >&2
    local dir pid pids=()
    for dir in "$VENV" "$ROOT"; do
        ( cd "$dir" && "$VENV/bin/python" -m gyro_emulator.sensor.warm_cache >/dev/null ) &
        pids+=($!)
    done
    for pid in "${pids[@]}"; do
        wait "$pid" || echo "dev.sh: warning: the sensor kernel was not cached;" \
            "the first start compiles it" >&2
    done
}

setup() {
    # Serialise concurrent callers (parallel shells share one .venv).
    mkdir -p "$VENV"
    exec 9>"$VENV.lock"
    flock 9
    local deps_stamp="$VENV/.deps_stamp" pkg_stamp="$VENV/.pkg_stamp" want
    if [ ! -x "$VENV/bin/python" ]; then
        local py; py=$(pick_python)
        echo "dev.sh: creating $VENV with $py" >&2
        if ! "$py" -m venv "$VENV"; then
            rm -rf "$VENV"
            echo "dev.sh: '$py -m venv' failed. On Debian 12: apt-get install python3-venv" >&2
            return 1
        fi
    fi
    want=$(sha256sum requirements.txt | cut -d' ' -f1)
    if [ "$(cat "$deps_stamp" 2>/dev/null)" != "$want" ]; then
        echo "dev.sh: installing pinned dependencies into $VENV (about 40 s the first time)" >&2
        "$VENV/bin/python" -m pip install -q --disable-pip-version-check -r requirements.txt
        echo "$want" > "$deps_stamp"
    fi
    # (Re)install the package itself whenever any source file changed. A regular
    # install puts console scripts in bin/ and config/launch/ament marker in share/.
    want=$( { git ls-files -co --exclude-standard -z 2>/dev/null || find . -path ./.venv -prune -o -type f -print0; } |
        LC_ALL=C sort -z | xargs -0 sha256sum 2>/dev/null | sha256sum | cut -d' ' -f1)
    if [ "$(cat "$pkg_stamp" 2>/dev/null)" != "$want" ]; then
        echo "dev.sh: installing gyro_emulator into $VENV" >&2
        "$VENV/bin/python" -m pip install -q --disable-pip-version-check --no-deps \
            --no-build-isolation --force-reinstall .
        rm -rf build gyro_emulator.egg-info
        warm_cache
        echo "$want" > "$pkg_stamp"
    fi
    flock -u 9
}

activate() {
    export VIRTUAL_ENV="$VENV"
    export PATH="$VENV/bin:$PATH"
    export AMENT_PREFIX_PATH="$VENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
    export MPLBACKEND=Agg
    # Small matrix work (ZOH, expm) stalls when OpenBLAS threads wait for a core.
    export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
    # Network rule: DDS discovery stays on this machine, on a domain of our own.
    export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
    export ROS_DOMAIN_ID="${ROS_DOMAIN_ID:-$(( ($$ % 90) + 10 ))}"
}

shell_rc() {
    # The rc file of ./dev.sh shell: the user's ~/.bashrc, then activate(), so
    # PATH edits made there (pyenv, conda) cannot hide the venv's python.
    printf '# Written by %s/dev.sh shell at each start: ~/.bashrc, then the venv.\n' "$ROOT"
    echo '[ -f ~/.bashrc ] && . ~/.bashrc'
    printf 'VENV=%q\n' "$VENV"
    declare -f activate
    cat <<'EOF'
activate
unset -f activate
case ":${PYTHONPATH:-}:" in
    *python3.1[2-9]*)
        echo "dev.sh shell: PYTHONPATH holds another Python's packages (a ROS" \
            "setup.bash in ~/.bashrc?); the venv's Python 3.11 cannot load them." \
            "See README.md, ROS 2 usage." >&2 ;;
esac
PS1="(gyro_emulator) ${PS1-\$ }"
EOF
}

cmd="${1:-}"
[ $# -gt 0 ] && shift
case "$cmd" in
    setup) setup ;;
    main)
        setup; activate
        exec "$VENV/bin/python" -m gyro_emulator.cli.main_job "$@" ;;
    test)
        setup; activate
        # testpaths=test (setup.cfg) applies when no path is given. The whole
        # suite runs on three pytest-xdist workers, a test file per worker: most
        # of its time is spent waiting (ROS discovery, child processes), so a
        # third worker on two cores halves the wall time (GYRO_TEST_WORKERS=0
        # runs it in one process), and names its 15 slowest tests; named tests run as given.
        if [ $# -eq 0 ]; then
            set -- -n "${GYRO_TEST_WORKERS:-3}" --dist loadfile --durations=15
        fi
        exec "$VENV/bin/python" -m pytest "$@" ;;
    shell)
        # bash, whatever $SHELL is: --rcfile is how the venv comes after ~/.bashrc.
        setup
        rc="$VENV/shell.bashrc"
        shell_rc > "$rc.$$"
        mv "$rc.$$" "$rc"
        exec bash --rcfile "$rc" -i "$@" ;;
    *)
        sed -n '2,15p' "$0" | sed 's/^# \{0,1\}//'
        exit 2 ;;
esac
