#!/usr/bin/env bash
# Every test: the firmware size budgets (G431 classic and CAN FD, G0B1), the firmware on an
# emulated Cortex-M4F and on the FPU-less Cortex-M0+ instruction set (QEMU) with bit-parity
# against the PC (f32 and Q16.16 steps), the control step's instruction budgets on both cores,
# the core's no-panic lints, and the host test suite (core, CANopen, host-sim, identification,
# diagnosis, python-canopen interop, end-to-end), and the diagnosis's null test on 500
# generated logs.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
echo "== format (cargo fmt --check; rustfmt.toml)"
cargo fmt --all -- --check
# The G0B1 and QEMU images and the porting example are workspaces of their own: --all above
# does not reach them.
cargo fmt --manifest-path firmware/board-g0b1/Cargo.toml -- --check
cargo fmt --manifest-path firmware/qemu/Cargo.toml -- --check
cargo fmt --manifest-path firmware/port-f4/Cargo.toml -- --check
echo "== host crates keep their dependency rules (cargo tree)"
bash scripts/check-deps.sh --self-test
bash scripts/check-deps.sh
echo "== firmware image size, STM32G431 (budget: flash ≤ 96 KiB, RAM ≤ 16 KiB)"
bash scripts/fw-size.sh g431
echo "== firmware image size, STM32G431 built for CAN FD (feature fd: 1/5 Mbit/s, BRS; same budget)"
bash scripts/fw-size.sh g431-fd
echo "== firmware image size, STM32G0B1, Q16.16 step (budget: flash ≤ 120 KiB, RAM ≤ 16 KiB)"
bash scripts/fw-size.sh g0b1
echo "== porting example: the core on an STM32F405 through stm32f4xx-hal, a HAL our boards do not use (docs/porting.md)"
cargo build -q --release --manifest-path firmware/port-f4/Cargo.toml --target thumbv7em-none-eabihf
echo "== firmware on QEMU (mps2-an386, Cortex-M4F)"
bash scripts/qemu-test.sh m4f
echo "== firmware on QEMU (mps2-an385: the M0+ instruction set without FPU; f32 soft-float and Q16.16)"
bash scripts/qemu-test.sh m0
echo "== control step cost on QEMU (instructions, -icount; full step budget ≤ 400 on the M4F, Q16.16 ≤ 2500 on the M0+; no row above scripts/fw-bench-baseline.txt)"
bash scripts/fw-bench.sh --self-test
bash scripts/fw-bench.sh
echo "== core lints (no unwrap/expect/panic/indexing in shipping code; its tests linted too, with their allows)"
cargo clippy -q -p joint-core --all-targets -- -D warnings
echo "== board image lints (G431 classic and CAN FD, G0B1)"
cargo clippy -q --profile fw -p firmware --target thumbv7em-none-eabihf -- -D warnings
cargo clippy -q --profile fw -p firmware --target thumbv7em-none-eabihf --features fd -- -D warnings
cargo clippy -q --profile fw --manifest-path firmware/board-g0b1/Cargo.toml --target thumbv6m-none-eabi -- -D warnings
# CI (.ci/run sets JOINT_CI_PRUNE=1) runs on a machine whose free disk we do not set: a run
# stopped on a full disk while linking the host tests (2026-11-30, 570 s in). The firmware
# builds above (all workspaces share target/, .cargo/config.toml) are done with by now: their
# host-side build scripts in target/fw and the images in target/<triple>, 1.5 GiB, removed
# before the host builds. target/qemu-parity stays (the host suite's QEMU parity test would
# build its images there again). A developer's run keeps them all.
prune() {
    if [ "${JOINT_CI_PRUNE:-0}" = 1 ]; then
        local dirs=()
        for d in "$@"; do [ -e "$d" ] && dirs+=("$d"); done
        if [ ${#dirs[@]} -gt 0 ]; then
            echo "== CI: removing ${dirs[*]} ($(du -sch "${dirs[@]}" | tail -n 1 | cut -f1); not needed by the steps below)"
            rm -rf "${dirs[@]}"
        fi
    fi
}
TARGET_DIR=${CARGO_TARGET_DIR:-target}
prune "$TARGET_DIR/fw" "$TARGET_DIR/thumbv6m-none-eabi" "$TARGET_DIR/thumbv7em-none-eabihf"
echo "== host crate lints (formats, simulator, CAN stack, analysis, jointctl)"
cargo clippy -q -p joint-formats -p host-sim -p joint-can -p joint-analysis -p jointctl -p diag-bench --lib --bins -- -D warnings
echo "== python peers for the CAN interop test (python-can, canopen)"
bash scripts/python-venv.sh
echo "== headless Chromium for the diagnosis report test"
bash scripts/chromium.sh
echo "== host test suite"
cargo test --workspace --no-fail-fast
# the null test builds its two binaries in release: the host tests' debug build is done with
prune "$TARGET_DIR/debug"
echo "== null test: 500 model-exact logs from diag-bench diagnosed blind (named an effect ≤ 1 %, refused ≤ 1 %)"
bash scripts/null-test.sh 500 31
