#!/usr/bin/env bash
# The host crates' dependency rules (each crate's top doc comment states its own), checked on
# the resolved graph so the layout cannot silently erode: `cargo tree -e normal` lists every
# crate a library pulls in (dev-dependencies and build tools aside), and a forbidden name
# anywhere in it fails with the path that brings it in.
#   scripts/check-deps.sh            check the workspace
#   scripts/check-deps.sh --self-test  show that a forbidden dependency is caught
set -euo pipefail
cd "$(dirname "$0")/.."

# crate: the packages it must never depend on, directly or through another crate
declare -A FORBIDDEN=(
    [joint-formats]="host-sim joint-can joint-analysis jointctl clap serialport socketcan indicatif ctrlc rand"
    [host-sim]="joint-analysis joint-can jointctl clap serialport socketcan indicatif ctrlc"
    [joint-can]="host-sim joint-analysis jointctl joint-formats clap indicatif ctrlc"
    [joint-analysis]="host-sim joint-can jointctl diag-bench clap serialport socketcan embedded-can indicatif ctrlc rand"
    # the independent bench: shares no code with what it judges
    [diag-bench]="joint-core joint-formats host-sim joint-can joint-analysis jointctl"
)

# check CRATE TREE_TEXT: prints each violation, returns 1 if any
check() {
    local crate=$1 tree=$2 bad=0 dep
    for dep in ${FORBIDDEN[$crate]}; do
        if grep -qE "^ *${dep} v" <<<"$tree"; then
            echo "check-deps: $crate depends on $dep, which its rules forbid:" >&2
            cargo tree -q -p "$crate" -e normal -i "$dep" 2>/dev/null | sed 's/^/    /' >&2 || true
            bad=1
        fi
    done
    return $bad
}

if [[ "${1:-}" == "--self-test" ]]; then
    # A tree as cargo prints it, with clap brought in by the analysis: the check must refuse it.
    fake=$'joint-analysis v0.1.0\njoint-core v0.1.0\nclap v4.5.0\nserde v1.0.0'
    if check joint-analysis "$fake" 2>/dev/null; then
        echo "check-deps: self-test FAILED: clap in joint-analysis was not caught" >&2
        exit 1
    fi
    echo "check-deps: self-test ok (a forbidden dependency is refused)"
    exit 0
fi

status=0
for crate in "${!FORBIDDEN[@]}"; do
    tree=$(cargo tree -q -p "$crate" -e normal --prefix none --no-dedupe)
    if check "$crate" "$tree"; then
        echo "check-deps: $crate ok ($(sort -u <<<"$tree" | wc -l) crates, none forbidden)"
    else
        status=1
    fi
done
exit $status
