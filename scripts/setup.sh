#!/usr/bin/env bash
# Idempotent setup for a fresh Debian 12 machine with rustup: the Cortex-M targets, llvm-tools
# (llvm-size for the firmware size report), qemu-system-arm (firmware tests on an emulated
# Cortex-M4F), socat (a pty pair that carries slcan between two programs) and can-utils (its
# offline log converters read the bus captures jointctl writes).
# Everything the README's two commands need is installed here, never by hand.
#   setup.sh           both parts
#   setup.sh --rust    the Rust targets and components only
#   setup.sh --apt     the Debian packages only (scripts/test.sh runs this part in the background
#                      while the firmware compiles)
set -euo pipefail
cd "$(dirname "$0")/.."
part="${1:-all}"
case "$part" in all|--rust|--apt) ;; *) echo "usage: setup.sh [--rust|--apt]" >&2; exit 2 ;; esac

log() { printf '\033[1msetup:\033[0m %s\n' "$*" >&2; }

if ! command -v cargo >/dev/null 2>&1; then
    if [ -x "$HOME/.cargo/bin/cargo" ]; then
        export PATH="$HOME/.cargo/bin:$PATH"
    else
        echo "setup: cargo/rustup not found; install Rust with rustup first" >&2
        exit 1
    fi
fi

rust_part() {
    # thumbv7em: the G431 (Cortex-M4F); thumbv6m: the FPU-less G0B1 (Cortex-M0+) and its QEMU images.
    for target in thumbv7em-none-eabihf thumbv6m-none-eabi; do
        if ! rustup target list --installed | grep -qx "$target"; then
            log "adding rust target $target"
            rustup target add "$target" >&2
        fi
    done
    if ! rustup component list --installed | grep -q '^llvm-tools'; then
        log "adding rustup component llvm-tools"
        rustup component add llvm-tools >&2
    fi
}

apt_part() {
    local need_apt=() pkg SUDO=""
    for pkg in qemu-system-arm socat can-utils; do
        dpkg -s "$pkg" >/dev/null 2>&1 || need_apt+=("$pkg")
    done
    if [ ${#need_apt[@]} -gt 0 ]; then
        [ "$(id -u)" -eq 0 ] || SUDO="sudo"
        log "installing Debian packages: ${need_apt[*]}"
        $SUDO apt-get update -qq >&2
        DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need_apt[@]}" >&2
    fi
}

[ "$part" = --apt ] || rust_part
[ "$part" = --rust ] || apt_part
log "ready"
