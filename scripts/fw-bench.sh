#!/usr/bin/env bash
# Instructions per compensation step, measured under QEMU with -icount shift=7 (SysTick counts
# instructions, ~3.2 ticks each; each image calibrates that ratio itself on a loop of known
# length), on two cores:
#   - the Cortex-M4F (thumbv7em-none-eabihf, hard float) on mps2-an386: budget 400 for the full
#     f32 step with the fused 2-D gravity table;
#   - the FPU-less Cortex-M0+ instruction set (thumbv6m-none-eabi, the STM32G0B1's; f32 in
#     soft-float) on mps2-an385, a Cortex-M3 without FPU (why not QEMU's M0 machine, microbit:
#     see scripts/qemu-test.sh): budget 2500 for the Q16.16 full step.
# Prints both tables, then the full step side by side (f32 and Q16.16 on both cores). Exits
# 0 when both images are within their budgets, 2 when one is over, 1 on panic, 124 on timeout.
set -uo pipefail
cd "$(dirname "$0")/.."
TARGET_DIR=${CARGO_TARGET_DIR:-target}
LOG_DIR=$(mktemp -d)
trap 'rm -rf "$LOG_DIR"' EXIT

status=0
run() { # CORE TARGET MACHINE
    local core=$1 target=$2 machine=$3 st
    cargo build --profile fw --manifest-path firmware/qemu/Cargo.toml --bin qemu-bench --target "$target" \
        --target-dir "$TARGET_DIR" >&2 || return 2
    echo "== $core"
    timeout "${QEMU_TIMEOUT:-120}" qemu-system-arm -M "$machine" -nographic \
        -semihosting-config enable=on,target=native -icount shift=7 \
        -kernel "$TARGET_DIR/$target/fw/qemu-bench" >"$LOG_DIR/$core.out"
    st=$?
    grep -v '^bench ' "$LOG_DIR/$core.out"
    return $st
}
run m4f thumbv7em-none-eabihf mps2-an386 || status=$?
run m0 thumbv6m-none-eabi mps2-an385 || { st=$?; [[ $status -eq 0 ]] && status=$st; }

full() { # CORE NAME -> the figure, or "?"
    grep -F "bench full \"$2\" " "$LOG_DIR/$1.out" 2>/dev/null | awk '{print $NF}' | grep . || echo "?"
}
echo "== full step, instructions (trunk joint + inertia/offset + spring, assist mode; the same with gravity)"
printf '| %-40s | %8s | %11s | %20s | %11s |\n' "" "M4F f32" "M4F Q16.16" "M0+ soft-float f32" "M0+ Q16.16"
printf '|%s|%s|%s|%s|%s|\n' "------------------------------------------" "----------" "-------------" "----------------------" "-------------"
for row in "full step" "full step + Dahl state (walk)" "full step + 2-D table, fused" \
    "full step, arm: series + residual table"; do
    printf '| %-40s | %8s | %11s | %20s | %11s |\n' "${row/ (walk)/}" \
        "$(full m4f "f32 $row")" "$(full m4f "Q16.16 $row")" "$(full m0 "f32 $row")" "$(full m0 "Q16.16 $row")"
done
exit $status
