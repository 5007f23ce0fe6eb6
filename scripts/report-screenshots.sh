#!/usr/bin/env bash
# Screenshots of the HTML reports for the docs (docs/img/*.png), from simulated logs:
#   - diagnosis: the trunk joint with a Stribeck dip the model file lacks (3 × 60 s at 1 kHz),
#     diagnosed against examples/models/trunk-right.toml;
#   - identification: the trunk joint's sweep, poses and hand tests (3 × 40 s), identified.
# Each report is opened in headless Chromium (scripts/chromium.sh installs it) after its
# inline viewer has run, and the page captured at 1200 px wide. Re-run after changing a report:
#   scripts/report-screenshots.sh [OUT_DIR]     (reports kept in OUT_DIR, default out/report-shots)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/report-shots}
mkdir -p "$out" docs/img
bash scripts/chromium.sh >/dev/null
command -v chromium >/dev/null || { echo "report-screenshots: no chromium (scripts/chromium.sh could not install it)" >&2; exit 1; }
cargo build --release -q -p jointctl --bin jointctl
j=target/release/jointctl

"$j" simulate --plant examples/plants/trunk-right-stribeck.toml --controller examples/models/trunk-right.toml \
    --scenario sweep,poses,hand --seconds 60 --seed 3 --out "$out/stribeck.csv"
"$j" diagnose --log "$out/stribeck.csv" --model examples/models/trunk-right.toml --report "$out/diagnose.html" \
    --json "$out/diagnose.json"

"$j" simulate --plant examples/plants/trunk-right.toml --controller examples/models/trunk-right.toml \
    --scenario sweep,poses,hand --seconds 40 --seed 1 --out "$out/trunk.csv"
"$j" identify --log "$out/trunk.csv" --out "$out/identified.toml" --report "$out/identify" --quiet

# shot HTML PNG HEIGHT: the page at 1200 px wide after its script ran (virtual time)
shot() {
    chromium --headless --no-sandbox --disable-gpu --hide-scrollbars --disable-background-networking \
        --virtual-time-budget=5000 --window-size=1200,"$3" --screenshot="$2" "file://$(realpath "$1")" 2>/dev/null
    echo "report-screenshots: $2 ($(du -k "$2" | cut -f1) kB)"
}
shot "$out/diagnose.html" docs/img/diagnose-report.png 1700
shot "$out/identify/report.html" docs/img/identify-report.png 1800
