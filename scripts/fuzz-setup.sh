# Sourced by the fuzz scripts: a nightly toolchain must be there, cargo-fuzz is installed once,
# the fuzz builds go to their own target folder. $1: the calling script's name, for messages.
# Leaves the shell in fuzz/.
fuzz_setup() {
    local who="$1"
    if ! rustup toolchain list | grep -q '^nightly'; then
        echo "$who: needs a nightly toolchain (rustup toolchain install nightly)" >&2
        exit 2
    fi
    if ! cargo fuzz --version >/dev/null 2>&1; then
        echo "$who: installing cargo-fuzz (once)" >&2
        cargo install cargo-fuzz --locked >&2
    fi
    cd fuzz
    export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-../target-fuzz}"
}
