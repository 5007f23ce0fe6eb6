#!/usr/bin/env bash
# Runs the joint core on QEMU's mps2-an386 (Cortex-M4F) and checks it against the host:
#   1. builds the QEMU images (firmware-qemu, profile fw, thumbv7em-none-eabihf);
#   2. qemu-core-checks: on-target facts about the core, exit status counts;
#   3. qemu-parity: the scripted session's every output, compared bit for bit with the
#      same session computed natively (tests/tests/qemu_parity.rs reads this run's log);
#   4. qemu-canopen: a scripted CANopen session through the core's node (NMT, SDO pushes with
#      aborts, commit, save, RPDOs, heartbeat loss) interleaved with 1 kHz control steps;
#      every frame the node sends and every control output compared byte for byte with the
#      host's run of the same script.
# Exits non-zero on any failure, a timeout included. Prints "N passed, M failed".
set -uo pipefail
cd "$(dirname "$0")/.."

TARGET=thumbv7em-none-eabihf
TARGET_DIR=${CARGO_TARGET_DIR:-target}
case "$TARGET_DIR" in /*) ;; *) TARGET_DIR="$PWD/$TARGET_DIR" ;; esac
BIN="$TARGET_DIR/$TARGET/fw"
QEMU_TIMEOUT=${QEMU_TIMEOUT:-60}
LOG_DIR=$(mktemp -d)
trap 'rm -rf "$LOG_DIR"' EXIT

command -v qemu-system-arm >/dev/null || { echo "qemu-test: qemu-system-arm not installed (apt-get install qemu-system-arm)" >&2; exit 2; }

cargo build --profile fw -p firmware-qemu --target "$TARGET" || { echo "qemu-test: build failed" >&2; exit 2; }

qemu() { # ELF -> runs it, stdout to $LOG_DIR/NAME.out, returns QEMU's exit status
    local elf=$1 name
    name=$(basename "$elf")
    timeout "$QEMU_TIMEOUT" qemu-system-arm -M mps2-an386 -nographic \
        -semihosting-config enable=on,target=native -icount shift=7 -kernel "$elf" \
        >"$LOG_DIR/$name.out"
}

passed=0
failed=0
result() { # NAME STATUS
    if [[ $2 -eq 0 ]]; then passed=$((passed + 1)); echo "qemu-test: $1 ok"
    else failed=$((failed + 1)); echo "qemu-test: $1 FAILED (exit $2${3:+, $3})"; fi
}
explain() {
    case $1 in 1) echo "panic" ;; 2) echo "check failed" ;; 3) echo "CPU fault" ;;
        124) echo "timed out after ${QEMU_TIMEOUT}s" ;; *) echo "" ;; esac
}

qemu "$BIN/qemu-core-checks"; st=$?
cat "$LOG_DIR/qemu-core-checks.out"
result "core checks on Cortex-M4F" $st "$(explain $st)"

qemu "$BIN/qemu-parity"; st=$?
if [[ $st -ne 0 ]]; then
    result "parity image run" $st "$(explain $st)"
else
    echo "qemu-test: parity image printed $(grep -c '^[RS] ' "$LOG_DIR/qemu-parity.out") records; comparing with the host"
    QEMU_PARITY_LOG="$LOG_DIR/qemu-parity.out" cargo test -p joint-tests --test qemu_parity -- --nocapture \
        qemu_matches_host_to_the_last_bit a_single_bit_difference
    result "parity QEMU vs host, bit for bit" $?
fi

qemu "$BIN/qemu-canopen"; st=$?
if [[ $st -ne 0 ]]; then
    result "CANopen session image run" $st "$(explain $st)"
else
    echo "qemu-test: CANopen image printed $(grep -c '^[TC] ' "$LOG_DIR/qemu-canopen.out") lines; comparing with the host"
    # The node's peak stack on a Cortex-M4F (building it with a stored set, and the session)
    # must fit the G431's 32 KiB of RAM beside the static data: with the 12 KiB stretch budget
    # for statics (scripts/fw-size.sh checks those), 20 KiB are left for the stack.
    grep '^# stack ' "$LOG_DIR/qemu-canopen.out" | sed 's/^# /qemu-test: CANopen node /'
    peak=$(grep '^# stack ' "$LOG_DIR/qemu-canopen.out" | grep -o '[0-9]\+' | sort -n | tail -1)
    [[ -n "$peak" && "$peak" -le 20480 ]]
    result "CANopen node stack ${peak:-?} B within 20 KiB" $?
    QEMU_CANOPEN_LOG="$LOG_DIR/qemu-canopen.out" cargo test -p joint-tests --test qemu_parity -- --nocapture canopen
    result "CANopen session QEMU vs host, byte for byte" $?
fi

echo "$passed passed, $failed failed"
[[ $failed -eq 0 ]]
