#!/usr/bin/env bash
# Runs the joint core on QEMU and checks it against the host. `qemu-test.sh` (or `m4f`): the
# Cortex-M4F images (thumbv7em-none-eabihf) on mps2-an386. `qemu-test.sh m0`: the FPU-less
# images (thumbv6m-none-eabi: soft-float f32 and the Q16.16 step, the STM32G0B1 board's
# instruction set) on mps2-an385, a Cortex-M3 without FPU: thumbv6m code runs unchanged on an
# M3 (ARMv7-M executes every ARMv6-M instruction), so the instruction stream measured is the
# M0+'s. QEMU 7.2's only Cortex-M0 machine, `microbit` (nRF51), was tried: semihosting works
# and its SysTick counts (QEMU models one the real nRF51 lacks), but its 16 KiB of RAM do not
# hold these images (the parity and bench images lock up on a HardFault there; the node alone
# is ~9 KiB and needs 17-20 KiB of stack).
#   1. builds the QEMU images (firmware-qemu, its own workspace, profile fw);
#   2. qemu-core-checks: on-target facts about the core, exit status counts;
#   3. qemu-parity: the scripted session's every output, compared bit for bit with the
#      same session computed natively (tests/tests/qemu_parity.rs reads this run's log);
#   4. qemu-canopen: a scripted CANopen session through the core's node (NMT, SDO pushes with
#      aborts, commit, save, RPDOs, heartbeat loss) interleaved with 1 kHz control steps;
#      every frame the node sends and every control output compared byte for byte with the
#      host's run of the same script; then qemu-canopen-q16, the node with its control
#      step in Q16.16 (what the G0B1 image runs), compared the same way.
# Exits non-zero on any failure, a timeout included. Prints "N passed, M failed".
set -uo pipefail
cd "$(dirname "$0")/.."

CORE=${1:-m4f}
case "$CORE" in
    m4f) TARGET=thumbv7em-none-eabihf MACHINE=mps2-an386 CORE_NAME="Cortex-M4F"
         # The G431 has 32 KiB of RAM: with the 16 KiB budget for statics (scripts/fw-size.sh
         # checks those; the node is one of them, in a static cell), 16 KiB are left for the
         # stack. Here the node is a local, so the stack beyond the node is what is checked.
         STACK_BUDGET=16384 BEYOND_NODE=1 ;;
    m0)  TARGET=thumbv6m-none-eabi MACHINE=mps2-an385 CORE_NAME="Cortex-M0+ code on an FPU-less M3"
         # The G0B1 has 144 KiB of RAM, plenty; the budget guards against regressions: the
         # stack beyond the node (a static on the board, as on the G431) measured 16.1 KiB for
         # the Q16.16 node after the CANopen services of issue 21 (Thumb-1 and soft-float take
         # more than the M4F's 14.1 KiB), plus ~25 %.
         STACK_BUDGET=20480 BEYOND_NODE=1 ;;
    *) echo "usage: qemu-test.sh [m4f|m0]" >&2; exit 2 ;;
esac
TARGET_DIR=${CARGO_TARGET_DIR:-target}
case "$TARGET_DIR" in /*) ;; *) TARGET_DIR="$PWD/$TARGET_DIR" ;; esac
BIN="$TARGET_DIR/$TARGET/fw"
QEMU_TIMEOUT=${QEMU_TIMEOUT:-60}
LOG_DIR=$(mktemp -d)
trap 'rm -rf "$LOG_DIR"' EXIT

command -v qemu-system-arm >/dev/null || { echo "qemu-test: qemu-system-arm not installed (apt-get install qemu-system-arm)" >&2; exit 2; }

# the images are a workspace of their own (firmware/qemu/Cargo.toml), built into this target folder
cargo build --profile fw --manifest-path firmware/qemu/Cargo.toml --target "$TARGET" --target-dir "$TARGET_DIR" || { echo "qemu-test: build failed" >&2; exit 2; }

qemu() { # ELF -> runs it, stdout to $LOG_DIR/NAME.out, returns QEMU's exit status
    local elf=$1 name
    name=$(basename "$elf")
    timeout "$QEMU_TIMEOUT" qemu-system-arm -M "$MACHINE" -nographic \
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
result "core checks on $CORE_NAME" $st "$(explain $st)"

qemu "$BIN/qemu-parity"; st=$?
if [[ $st -ne 0 ]]; then
    result "parity image run" $st "$(explain $st)"
else
    echo "qemu-test: parity image printed $(grep -c '^[RSQ] ' "$LOG_DIR/qemu-parity.out") records; comparing with the host"
    QEMU_PARITY_LOG="$LOG_DIR/qemu-parity.out" cargo test -p joint-tests --test qemu_parity -- --nocapture \
        qemu_matches_host_to_the_last_bit a_single_bit_difference
    result "parity QEMU vs host, bit for bit" $?
fi

canopen() { # IMAGE LOG_VAR TEST_FILTER LABEL [nostack]
    local img=$1 var=$2 filter=$3 label=$4 nostack=${5:-} st peak
    qemu "$BIN/$img"; st=$?
    if [[ $st -ne 0 ]]; then
        result "$label image run" $st "$(explain $st)"
        return
    fi
    echo "qemu-test: $img printed $(grep -c '^[TC] ' "$LOG_DIR/$img.out") lines; comparing with the host"
    # The node's peak stack (building it with a stored set, and the session) must fit the
    # board's RAM beside the static data (STACK_BUDGET above says why that much).
    grep '^# stack \|^# node ' "$LOG_DIR/$img.out" | sed 's/^# /qemu-test: CANopen node /'
    peak=$(grep '^# stack ' "$LOG_DIR/$img.out" | grep -o '[0-9]\+' | sort -n | tail -1)
    node=$(grep '^# node size=' "$LOG_DIR/$img.out" | grep -o '[0-9]\+' | head -1)
    what="node stack"
    if [[ $BEYOND_NODE == 1 && -n "$peak" && -n "$node" ]]; then
        peak=$((peak - node)) what="stack beyond the node (${node} B, a static on the board)"
    fi
    if [[ -z "$nostack" ]]; then
        [[ -n "$peak" && "$peak" -le $STACK_BUDGET ]]
        result "$label $what ${peak:-?} B within $((STACK_BUDGET / 1024)) KiB" $?
    fi
    env "$var=$LOG_DIR/$img.out" cargo test -p joint-tests --test qemu_parity -- --nocapture --exact "$filter"
    result "$label QEMU vs host, byte for byte" $?
}
canopen qemu-canopen QEMU_CANOPEN_LOG canopen_session_on_qemu_matches_host_byte_for_byte "CANopen session (f32 node)"
# The Q16.16 node on both cores: on the M0+ it is what the G0B1 image runs; on the M4F it is
# the same integer code through another compiler back end (and scripts/test.sh leaves these
# comparisons out of the host suite, which would otherwise build and run the images again).
# No board runs the Q16.16 node on an M4F: its stack budget is checked on m0 only (16.3 KiB
# beyond the node here, over the G431's 16 KiB, which only its f32 node has to fit).
q16_stack=""
[[ $CORE == m0 ]] || q16_stack=nostack
canopen qemu-canopen-q16 QEMU_CANOPEN_Q16_LOG canopen_session_q16_on_qemu_matches_host_byte_for_byte \
    "CANopen session (Q16.16 node)" $q16_stack

echo "$passed passed, $failed failed"
[[ $failed -eq 0 ]]
