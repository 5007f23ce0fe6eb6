#!/usr/bin/env bash
# Python peers for the CAN interop test (tests/python/test_interop.py): python-can (slcan) and
# python-canopen, in the repository's ./.venv (shared with the other Python helpers; this only
# adds what the CAN test needs). Idempotent: installs only what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv/bin/python ]; then
    python3 -m venv .venv
fi
if ! .venv/bin/python - <<'PY' 2>/dev/null
import can, canopen, pytest, serial
assert can.__version__.startswith("4."), can.__version__
assert canopen.__version__.startswith("2."), canopen.__version__
PY
then
    .venv/bin/pip install --quiet --disable-pip-version-check \
        "python-can>=4.4,<5" "canopen>=2.3,<3" "pyserial>=3.5,<4" "pytest>=7,<9"
fi
.venv/bin/python -c "import can, canopen, pytest; print('python-can', can.__version__, 'canopen', canopen.__version__, 'pytest', pytest.__version__)"
