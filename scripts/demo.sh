#!/usr/bin/env bash
# The main job on the embedded default, no hardware: the trunk-exoskeleton right joint
# (trunk paper Table 1) simulated with the firmware's own core running the compensation law
# at 1 kHz (fraction 0.7, as the paper), moved by a simulated operator's hand for 20 s.
# Writes out/demo-trunk-right.csv (the joint-log CSV of the spec) and prints a summary.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
mkdir -p out
cargo run --release -q -p jointctl --bin jointctl -- simulate \
    --plant examples/plants/trunk-right.toml \
    --controller examples/models/trunk-right.toml \
    --scenario hand --seconds 20 --seed 1 \
    --out out/demo-trunk-right.csv
