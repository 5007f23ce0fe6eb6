#!/usr/bin/env bash
# The 1 M-sample diagnosis against the NumPy/SciPy version of the same analysis, back to back on
# the same file (docs/diagnosis.md, "Performance"). Builds the Rust bench, generates the log once
# (kept in target/diag-bench), then alternates RUNS runs of each implementation and prints every
# figure and the ratios. Both implementations print their verdict and held-out RMSE, so a
# speed-up that changed the result would show. By hand, not in CI (about a minute).
#   scripts/bench-vs-numpy.sh [RUNS]     (default 3)
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-3}"
bash scripts/python-venv-diag.sh > /dev/null
dir="$PWD/target/diag-bench"
mkdir -p "$dir"
# First run: builds the bench and writes bench-1m.csv/bench-model.toml into $dir if missing.
DIAG_BENCH_KEEP="$dir" cargo bench -q -p joint-analysis --bench diagnose > /dev/null
csv="$dir/bench-1m.csv" model="$dir/bench-model.toml"
rust=() numpy=() lstsq=()
figure() { sed -n 's/.*total_s=\([0-9.]*\).*/\1/p'; }
for i in $(seq "$runs"); do
    r=$(DIAG_BENCH_KEEP="$dir" cargo bench -q -p joint-analysis --bench diagnose | tee /dev/stderr | grep DIAG_BENCH | figure)
    n=$(.venv/bin/python tests/python/bench_numpy_diagnose.py "$csv" "$model" | tee /dev/stderr | grep NUMPY_BENCH | figure)
    l=$(.venv/bin/python tests/python/bench_numpy_diagnose.py --lstsq "$csv" "$model" | tee /dev/stderr | grep NUMPY_BENCH | figure)
    rust+=("$r") numpy+=("$n") lstsq+=("$l")
done
python3 - "${rust[*]}" "${numpy[*]}" "${lstsq[*]}" <<'EOF'
import sys
rust, numpy, lstsq = ([float(x) for x in a.split()] for a in sys.argv[1:4])
span = lambda v: f"{min(v):.3f}–{max(v):.3f} s"
print(f"Rust (jointctl diagnose code path)        {span(rust)}")
print(f"NumPy, same algorithm (bordered)          {span(numpy)}   Rust faster by {min(numpy)/max(rust):.1f}–{max(numpy)/min(rust):.1f}×")
print(f"NumPy, np.linalg.lstsq at every grid point {span(lstsq)}   Rust faster by {min(lstsq)/max(rust):.1f}–{max(lstsq)/min(rust):.1f}×")
EOF
