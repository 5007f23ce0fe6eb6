#!/usr/bin/env bash
# Every measured log in ../shared/data/real through jointctl as a user runs it: import, identify
# (a model is written only where the log determines its terms), and diagnose against the
# nominal model each data set's README gives (docs/diagnosis.md, "Real logs", says why each).
# Prints one line per log: what identify wrote or why not, and the diagnosis verdict.
#   scripts/real-logs.sh [OUT_DIR]      (default target/real-logs; by hand, about a minute)
set -euo pipefail
cd "$(dirname "$0")/.."
real="$(cd .. && pwd)/shared/data/real"
out="${1:-target/real-logs}"
mkdir -p "$out"
cargo build -q --release -p jointctl
j=target/release/jointctl

# Nominal models: the DFKI authors' sys-id fit (Coulomb Fc·atan(100 q̇) as c = Fc·π/2 over
# v_band 0.02); Panda joint 1, the authors' Coulomb level and the inertia identified on the log;
# the Jensen pendulum, guessed from its README's period.
cat > "$out/dfki.toml" <<'EOF'
[friction]
b = 0.04707
c = 0.2889
v_band = 0.02

[weight]
amplitude = 1.0026
s = 1.0
phi = 0.0

[inertia]
j = 0.06259

[offset]
c0 = -0.07586
EOF
printf '[inertia]\nj = 1.16\n\n[friction]\nc = 0.273\nv_band = 0.2\n' > "$out/panda1.toml"
printf '[weight]\namplitude = 1.38\ns = 1.0\nphi = 0.0\n\n[inertia]\nj = 0.01\n\n[friction]\nb = 0.0002\n' > "$out/jensen.toml"

# name, import format, upstream file, import options, model for the diagnosis ("-": none)
logs=(
    "dfki-sysid|dfki-pendulum|dfki_simple_pendulum/sysid_pd_swingup_measured.csv||dfki.toml"
    "dfki-energy|dfki-pendulum|dfki_simple_pendulum/energy_shaping_measured.csv||dfki.toml"
    "dfki-energy-1kg|dfki-pendulum|dfki_simple_pendulum/energy_shaping_1kg_measured.csv||dfki.toml"
    "dfki-hand|dfki-pendulum|dfki_simple_pendulum/gravity_compensation_handmoved_measured.csv||dfki.toml"
    "dfki-double-j1|dfki-double-pendulum|dfki_double_pendulum/sysid_design_C1_20230629-143339_trajectory.csv|--joint 1|-"
    "dfki-double-j2|dfki-double-pendulum|dfki_double_pendulum/sysid_design_C1_20230629-143339_trajectory.csv|--joint 2|-"
    "panda-j1|panda-gaz|panda_gaz2019/panda_exciting_traj1_measured.csv|--joint 1|panda1.toml"
    "panda-j2|panda-gaz|panda_gaz2019/panda_exciting_traj1_measured.csv|--joint 2|-"
    "panda-j5|panda-gaz|panda_gaz2019/panda_exciting_traj1_measured.csv|--joint 5|-"
    "panda-j7|panda-gaz|panda_gaz2019/panda_exciting_traj1_measured.csv|--joint 7|-"
    "jensen-01|jensen-free-swing|free_swing_pendulum_jensen/free_swing_01.csv||jensen.toml"
    "jensen-02|jensen-free-swing|free_swing_pendulum_jensen/free_swing_02.csv||jensen.toml"
    "jensen-03|jensen-free-swing|free_swing_pendulum_jensen/free_swing_03.csv||jensen.toml"
)
for j0 in 0 1 2 3 4 5; do
    logs+=("ur5e-j$j0|ur5e-friction|ur5e_friction_calibration_aurt/ur5e_joint_friction_table.csv|--joint $j0|-")
done

for entry in "${logs[@]}"; do
    IFS='|' read -r name format file opts model <<< "$entry"
    [ -f "$real/$file" ] || { echo "$name: $real/$file not found"; continue; }
    # shellcheck disable=SC2086 # opts is a word list
    "$j" import --format "$format" --input "$real/$file" $opts --out "$out/$name.csv" > /dev/null 2>&1
    # identify's last line: what it wrote, or why nothing (its whole report in $name.identify.txt)
    "$j" identify --log "$out/$name.csv" --out "$out/$name.identified.toml" > "$out/$name.identify.txt" 2>&1 || true
    ident=$(tail -n 1 "$out/$name.identify.txt" | sed -e 's/^error: nothing written to [^:]*: /identify wrote nothing: /' \
        -e 's/ (tests that would pin them.*//' -e "s|^wrote $out/|identify wrote |")
    if [ "$model" = "-" ]; then
        echo "$name: $ident"
        continue
    fi
    verdict=$("$j" diagnose --log "$out/$name.csv" --model "$out/$model" --json "$out/$name.diagnose.json" 2>&1 \
        | grep '^verdict' || true)
    echo "$name: $ident; $verdict"
done
