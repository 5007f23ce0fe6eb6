#!/usr/bin/env bash
# Instructions per compensation step, measured under QEMU with -icount shift=7 (SysTick counts
# instructions, ~3.2 ticks each; each image calibrates that ratio itself on a loop of known
# length), on two cores:
#   - the Cortex-M4F (thumbv7em-none-eabihf, hard float) on mps2-an386: budget 400 for the full
#     f32 step with the fused 2-D gravity table;
#   - the FPU-less Cortex-M0+ instruction set (thumbv6m-none-eabi, the STM32G0B1's; f32 in
#     soft-float) on mps2-an385, a Cortex-M3 without FPU (why not QEMU's M0 machine, microbit:
#     see scripts/qemu-test.sh): budget 2500 for the Q16.16 full step.
# Prints both tables, then the full step side by side (f32 and Q16.16 on both cores), then every
# row against the committed baseline (scripts/fw-bench-baseline.txt: the `bench` lines of both
# images, one per row): a budget only catches a step that became much slower, the baseline
# catches any row that rose. A row may rise by at most max(1 instruction, 0.5 %): a
# change elsewhere in an image can move code across a flash line or an alignment boundary and
# cost an instruction where nothing in the step changed.
#   scripts/fw-bench.sh                    measure, check the budgets and the baseline
#   scripts/fw-bench.sh --update-baseline  measure and write the baseline (commit it with the
#                                          change that lowered a row, or say in the commit why
#                                          one rose)
#   scripts/fw-bench.sh --self-test        the comparison alone on made-up rows (no QEMU)
# Exits 0 when both images are within their budgets and no row rose, 2 when one is over its
# budget, 3 when a row rose above the baseline or a baseline row is gone, 1 on panic, 124 on
# timeout.
set -uo pipefail
cd "$(dirname "$0")/.."
TARGET_DIR=${CARGO_TARGET_DIR:-target}
LOG_DIR=$(mktemp -d)
trap 'rm -rf "$LOG_DIR"' EXIT

BASELINE=scripts/fw-bench-baseline.txt

# compare BASELINE CURRENT: both hold lines `CORE KIND "ROW" N`; prints every row with its
# baseline figure and the change, returns 3 when a row rose beyond the tolerance or a baseline
# row is missing from CURRENT, else 0.
compare() {
    awk '
        function key(line,   q1, q2) { q1 = index(line, "\""); q2 = q1 + index(substr(line, q1 + 1), "\"");
            return substr(line, 1, q2) }
        function val(line,   n, f) { n = split(line, f, " "); return f[n] + 0 }
        FNR == NR { k = key($0); base[k] = val($0); order[++nb] = k; next }
        { k = key($0); cur[k] = val($0); if (!(k in base)) extra[++ne] = k }
        END {
            bad = 0
            printf "%-70s %10s %10s %8s\n", "row (core kind \"name\")", "baseline", "now", "change"
            for (i = 1; i <= nb; i++) {
                k = order[i]; b = base[k]
                if (!(k in cur)) { printf "%-70s %10.1f %10s %8s  MISSING\n", k, b, "-", "-"; bad = 1; continue }
                c = cur[k]; tol = b * 0.005; if (tol < 1.0) tol = 1.0
                flag = ""
                if (c > b + tol) { flag = "  ROSE (tolerance " sprintf("%.1f", tol) ")"; bad = 1 }
                printf "%-70s %10.1f %10.1f %+8.1f%s\n", k, b, c, c - b, flag
            }
            for (i = 1; i <= ne; i++) printf "%-70s %10s %10.1f %8s  new (not in the baseline)\n", extra[i], "-", cur[extra[i]], "-"
            exit bad ? 3 : 0
        }' "$1" "$2"
}

if [[ "${1:-}" == "--self-test" ]]; then
    b=$(mktemp) c=$(mktemp)
    trap 'rm -f "$b" "$c"' EXIT
    printf '%s\n' 'm4f step "friction+weight" 218.4' 'm0 full "Q16.16 full step" 2154.1' 'm4f component "Friction::torque" 14.8' >"$b"
    fail() { echo "fw-bench: self-test FAILED: $1" >&2; exit 1; }
    # lower, equal and within the tolerance (2154.1 · 0.5 % = 10.8; 1 instruction below 200)
    printf '%s\n' 'm4f step "friction+weight" 219.3' 'm0 full "Q16.16 full step" 2164.0' 'm4f component "Friction::torque" 14.0' 'm0 step "new row" 5.0' >"$c"
    compare "$b" "$c" >/dev/null || fail "rows within the tolerance were refused"
    printf '%s\n' 'm4f step "friction+weight" 219.5' 'm0 full "Q16.16 full step" 2154.1' 'm4f component "Friction::torque" 14.8' >"$c"
    compare "$b" "$c" >/dev/null && fail "a row 1.1 instructions up was accepted"
    printf '%s\n' 'm4f step "friction+weight" 218.4' 'm0 full "Q16.16 full step" 2165.0' 'm4f component "Friction::torque" 14.8' >"$c"
    compare "$b" "$c" >/dev/null && fail "a row 0.51 % up was accepted"
    printf '%s\n' 'm4f step "friction+weight" 218.4' 'm4f component "Friction::torque" 14.8' >"$c"
    compare "$b" "$c" >/dev/null && fail "a missing row was accepted"
    echo "fw-bench: self-test ok (a row that rose or went missing is refused, one within the tolerance kept)"
    exit 0
fi

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
    "full step, arm: series + residual table" "full step + load friction"; do
    printf '| %-40s | %8s | %11s | %20s | %11s |\n' "${row/ (walk)/}" \
        "$(full m4f "f32 $row")" "$(full m4f "Q16.16 $row")" "$(full m0 "f32 $row")" "$(full m0 "Q16.16 $row")"
done
# Every row of both images against the baseline ("bench KIND NAME N" becomes "CORE KIND NAME N").
for core in m4f m0; do
    sed -n 's/^bench /'"$core"' /p' "$LOG_DIR/$core.out" 2>/dev/null
done >"$LOG_DIR/rows.txt"
if [[ "${1:-}" == "--update-baseline" ]]; then
    if [[ $status -eq 0 ]]; then
        cp "$LOG_DIR/rows.txt" "$BASELINE"
        echo "fw-bench: wrote $BASELINE ($(wc -l <"$BASELINE") rows)"
    else
        echo "fw-bench: a run failed (exit $status): baseline not written" >&2
    fi
    exit $status
fi
echo "== every row against the baseline ($BASELINE; a row may rise by max(1, 0.5 %))"
compare "$BASELINE" "$LOG_DIR/rows.txt"
st=$?
if [[ $st -ne 0 ]]; then
    echo "fw-bench: a row rose above the baseline or is missing (--update-baseline only for a rise the commit explains)"
    [[ $status -eq 0 ]] && status=$st
fi
exit $status
