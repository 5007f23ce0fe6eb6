#!/usr/bin/env bash
# Every test: the host test suite (core, host-sim, end-to-end), the firmware on an emulated
# Cortex-M4F (QEMU) with bit-parity against the PC, and the firmware size budget.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
echo "== firmware image size (budget: flash ≤ 64 KiB, RAM ≤ 16 KiB)"
bash scripts/fw-size.sh
echo "== firmware on QEMU (mps2-an386, Cortex-M4F)"
bash scripts/qemu-test.sh
echo "== host test suite"
cargo test --workspace --no-fail-fast
