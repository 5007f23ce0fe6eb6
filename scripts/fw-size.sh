#!/usr/bin/env bash
# Builds a board image (profile fw) and prints its flash and static RAM use against its budget.
#   fw-size.sh [g431]  the STM32G431 image: flash <= 96 KiB, static RAM <= 16 KiB (stretch
#                      64 KiB / 12 KiB). The G431CB has 128 KiB of flash, 8 KiB of it the
#                      parameter pages: 96 KiB keeps a quarter of the code region free. It was
#                      64 KiB (half the part) until the CANopen services a master expects (SDO
#                      block transfer, a second SDO channel, LSS, remappable PDOs, CAN FD) took
#                      the image to 68 KiB; the old figure is now the stretch goal.
#   fw-size.sh g431-fd the same image built for CAN FD (feature fd: 1/5 Mbit/s, BRS), same budget.
#   fw-size.sh g0b1    the STM32G0B1 image (Q16.16 step; `g0b1-f32` the soft-float one):
#                      flash <= 120 KiB so it fits the smallest G0B1 (xB: 128 KiB, minus the
#                      8 KiB parameter pages) and not only the NUCLEO's 512 KiB part; static
#                      RAM <= 16 KiB as on the G431 (every G0B1 has 144 KiB: the budget
#                      catches growth, not a limit of the part). Stretch 96 KiB / 12 KiB.
# Exits 1 when over budget, 2 when the build or the measurement itself fails.
#
# Flash = .vector_table + .text + .rodata + .data (its load image lives in flash);
# static RAM = .data + .bss + .uninit (the stack is not counted: it takes what is left).
set -euo pipefail
cd "$(dirname "$0")/.."

RAM_BUDGET=$((16 * 1024))
RAM_STRETCH=$((12 * 1024))
# CRATE: how cargo is told which image (the G0B1's is a workspace of its own:
# firmware/board-g0b1/Cargo.toml); MAP: the memory map the image must have been linked with.
G0B1=(--manifest-path firmware/board-g0b1/Cargo.toml)
case "${1:-g431}" in
    g431) TARGET=thumbv7em-none-eabihf PKG=firmware CRATE=(-p firmware) FEATURES=()
          MAP=memory.x FLASH_BUDGET=$((96 * 1024)) FLASH_STRETCH=$((64 * 1024)) ;;
    g431-fd) TARGET=thumbv7em-none-eabihf PKG=firmware CRATE=(-p firmware) FEATURES=(--features fd)
          MAP=memory.x FLASH_BUDGET=$((96 * 1024)) FLASH_STRETCH=$((64 * 1024)) ;;
    g0b1) TARGET=thumbv6m-none-eabi PKG=firmware-g0b1 CRATE=("${G0B1[@]}") FEATURES=()
          MAP=firmware/board-g0b1/memory.x FLASH_BUDGET=$((120 * 1024)) FLASH_STRETCH=$((96 * 1024)) ;;
    g0b1-f32) TARGET=thumbv6m-none-eabi PKG=firmware-g0b1 CRATE=("${G0B1[@]}") FEATURES=(--no-default-features)
          MAP=firmware/board-g0b1/memory.x FLASH_BUDGET=$((120 * 1024)) FLASH_STRETCH=$((96 * 1024)) ;;
    *) echo "usage: fw-size.sh [g431|g431-fd|g0b1|g0b1-f32]" >&2; exit 2 ;;
esac
echo "fw-size: $PKG ${FEATURES[*]} ($TARGET, map $MAP)"
TARGET_DIR=${CARGO_TARGET_DIR:-target}
LLVM_BIN="$(rustc --print sysroot)/lib/rustlib/x86_64-unknown-linux-gnu/bin"
LLVM_SIZE="$LLVM_BIN/llvm-size"
if [[ ! -x "$LLVM_SIZE" ]]; then
    echo "fw-size: llvm-size not found at $LLVM_SIZE (rustup component add llvm-tools)" >&2
    exit 2
fi

cargo build --profile fw "${CRATE[@]}" ${FEATURES[@]+"${FEATURES[@]}"} --target "$TARGET" >&2 || exit 2
ELF="$TARGET_DIR/$TARGET/fw/$PKG"
[[ -f "$ELF" ]] || { echo "fw-size: no image at $ELF" >&2; exit 2; }

# The image must carry its own board's map: a binary linked in a workspace whose root holds
# another board's memory.x links with that one without a complaint (lld takes the working
# directory's first). The parameter region's start and the stack top (the RAM's end) come from
# the map; the linker writes both into the ELF's symbols.
map_origin() { # REGION -> its ORIGIN in MAP, decimal
    awk -v r="$1" '$1 == r { for (i = 1; i <= NF; i++) if ($i == "ORIGIN") { v = $(i + 2); sub(/,$/, "", v); print v } }' "$MAP"
}
map_length() { # REGION -> its LENGTH in MAP, bytes (a K suffix is KiB)
    awk -v r="$1" '$1 == r { for (i = 1; i <= NF; i++) if ($i == "LENGTH") { v = $(i + 2); k = sub(/K$/, "", v); print v * (k ? 1024 : 1) } }' "$MAP"
}
elf_symbol() { "$LLVM_BIN/llvm-nm" "$ELF" | awk -v s="$1" '$3 == s { print $1 }'; }
want_params=$(( $(map_origin PARAMS) ))
want_stack=$(( $(map_origin RAM) + $(map_length RAM) ))
have_params=$(( 0x$(elf_symbol __param_start) ))
have_stack=$(( 0x$(elf_symbol _stack_start) ))
if (( have_params != want_params || have_stack != want_stack )); then
    printf 'fw-size: %s was not linked with %s: parameters at 0x%08x (map: 0x%08x), stack top 0x%08x (map: 0x%08x)\n' \
        "$ELF" "$MAP" "$have_params" "$want_params" "$have_stack" "$want_stack" >&2
    exit 2
fi
printf 'map: %s (parameters at 0x%08x, RAM ends at 0x%08x)\n' "$MAP" "$have_params" "$have_stack"

# llvm-size -A: "section size addr" rows.
read -r FLASH RAM < <("$LLVM_SIZE" -A "$ELF" | awk '
    $1 == ".vector_table" || $1 == ".text" || $1 == ".rodata" { flash += $2 }
    $1 == ".data" { flash += $2; ram += $2 }
    $1 == ".bss" || $1 == ".uninit" { ram += $2 }
    END { print flash + 0, ram + 0 }')

"$LLVM_SIZE" -A "$ELF" | awk '$1 ~ /^\.(vector_table|text|rodata|data|bss|uninit)$/' >&2
pct() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", 100 * a / b }'; }
printf 'flash: %6d bytes (%5.1f KiB) of %d KiB budget (%s %%), stretch %d KiB\n' \
    "$FLASH" "$(awk -v a="$FLASH" 'BEGIN{print a/1024}')" $((FLASH_BUDGET / 1024)) \
    "$(pct "$FLASH" "$FLASH_BUDGET")" $((FLASH_STRETCH / 1024))
printf 'ram:   %6d bytes (%5.1f KiB) of %d KiB budget (%s %%), stretch %d KiB\n' \
    "$RAM" "$(awk -v a="$RAM" 'BEGIN{print a/1024}')" $((RAM_BUDGET / 1024)) \
    "$(pct "$RAM" "$RAM_BUDGET")" $((RAM_STRETCH / 1024))

status=0
if (( FLASH > FLASH_BUDGET )); then echo "fw-size: flash over budget" >&2; status=1; fi
if (( RAM > RAM_BUDGET )); then echo "fw-size: static RAM over budget" >&2; status=1; fi
if (( status == 0 && FLASH <= FLASH_STRETCH && RAM <= RAM_STRETCH )); then
    echo "within the stretch budget too"
fi
exit $status
