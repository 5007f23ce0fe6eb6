#!/usr/bin/env bash
# Headless Chromium for the diagnosis report test (host-sim/jointctl/tests/diagnose_report.rs).
# Installs Debian's `chromium` package when missing; exits 0 either way and says what it did,
# the test itself skips with a message when no browser is there.
set -uo pipefail
if command -v chromium >/dev/null 2>&1; then
    echo "chromium: $(chromium --version 2>/dev/null)"
    exit 0
fi
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
if $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends chromium >/dev/null; then
    echo "chromium installed: $(chromium --version 2>/dev/null)"
else
    echo "chromium could not be installed; the HTML report test will skip" >&2
fi
exit 0
