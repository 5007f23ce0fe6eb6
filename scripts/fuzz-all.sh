#!/usr/bin/env bash
# Run every cargo-fuzz target (fuzz/fuzz_targets/: the CANopen node, the joint-log reader, the
# model TOML loader, the host SDO client) for RUNS executions each (default 1000000; issue 16
# quotes 10 M each, run by hand), starting from the seeds in fuzz/seeds/<target> (in the repo) and the local corpus in
# fuzz/corpus/<target> (grown by earlier runs, not committed).
# Prints one line per target: executions, seconds, result. Fails on any crash (the input is
# kept under fuzz/artifacts/<target>/). Needs a nightly toolchain; installs cargo-fuzz once.
#   scripts/fuzz-all.sh 10000000                 (every target)
#   scripts/fuzz-all.sh 10000000 canopen_node    (some: run two invocations to use two cores)
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-1000000}"
shift || true
targets=("$@")
if [ "${#targets[@]}" -eq 0 ]; then
    targets=(canopen_node joint_log model_toml sdo_client)
fi
# shellcheck source=scripts/fuzz-setup.sh
source scripts/fuzz-setup.sh
fuzz_setup fuzz-all
status=0
summary=()
for target in "${targets[@]}"; do
    mkdir -p "corpus/$target"
    # the run grows the local corpus; the repo's seeds are read only
    work="corpus/$target"
    cp -rn "seeds/$target/." "$work/" 2>/dev/null || true
    log=$(mktemp)
    start=$(date +%s)
    set +e
    # no sanitizer: the targets are safe Rust (debug assertions stay on), and ASan's 3-5x would
    # put 10 M runs of the node out of reach of a working session
    cargo +nightly fuzz run --sanitizer none "$target" "$work" -- -runs="$runs" -max_len=4096 -rss_limit_mb=2048 -malloc_limit_mb=512 \
        >"$log" 2>&1
    rc=$?
    set -e
    secs=$(( $(date +%s) - start ))
    execs=$(grep -oE "^#[0-9]+" "$log" | tail -1 | tr -d '#')
    if [ "$rc" -ne 0 ]; then
        grep -E "ERROR|panicked|SUMMARY|Test unit written" "$log" | head -20 >&2 || tail -30 "$log" >&2
        status=1
        result="CRASH (exit $rc)"
    else
        result="0 crashes"
    fi
    summary+=("$(printf '%-14s %12s executions  %5s s  %s' "$target" "${execs:-0}" "$secs" "$result")")
    rm -f "$log"
done
printf '%s\n' "${summary[@]}"
exit "$status"
