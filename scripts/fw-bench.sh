#!/usr/bin/env bash
# Instructions per compensation step on an emulated Cortex-M4F (QEMU mps2-an386 with
# -icount shift=7: SysTick counts instructions, ~3.2 ticks each; the image calibrates
# that ratio itself on a loop of known length). Prints the table; exits with the image's
# status: 0 when the full step (2-D fused gravity table) is within 400 instructions, 2
# when over, 1 on panic, 124 on timeout.
set -uo pipefail
cd "$(dirname "$0")/.."
TARGET=thumbv7em-none-eabihf
TARGET_DIR=${CARGO_TARGET_DIR:-target}
cargo build --profile fw -p firmware-qemu --bin qemu-bench --target "$TARGET" >&2 || exit 2
timeout "${QEMU_TIMEOUT:-60}" qemu-system-arm -M mps2-an386 -nographic \
    -semihosting-config enable=on,target=native -icount shift=7 \
    -kernel "$TARGET_DIR/$TARGET/fw/qemu-bench" | grep -v '^bench '
exit "${PIPESTATUS[0]}"
