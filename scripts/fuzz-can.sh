#!/usr/bin/env bash
# Fuzz the CANopen node's frame handling with libFuzzer (cargo-fuzz, nightly) for SECONDS
# (default 60; CI runs a short bound, run longer by hand). Prints the executions done and
# fails on any crash (the input is kept under fuzz/artifacts/).
#   scripts/fuzz-can.sh 600
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-60}"
mkdir -p fuzz/corpus/canopen_node
# shellcheck source=scripts/fuzz-setup.sh
source scripts/fuzz-setup.sh
fuzz_setup fuzz-can
log=$(mktemp)
set +e
cargo +nightly fuzz run canopen_node -- -max_total_time="$secs" -max_len=4096 2>&1 | tee "$log" | grep -E "^(#[0-9]+ +(INITED|DONE))|ERROR|panicked|SUMMARY|Done"
rc=${PIPESTATUS[0]}
set -e
execs=$(grep -oE "^#[0-9]+" "$log" | tail -1 | tr -d '#')
echo "fuzz-can: ${execs:-0} executions in ${secs} s, exit ${rc}"
rm -f "$log"
exit "$rc"
