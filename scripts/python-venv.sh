#!/usr/bin/env bash
# Python peers for the interop tests: python-can (slcan; its can-utils log reader and writer)
# and python-canopen (tests/python/test_interop.py), and the official MCAP tooling (mcap,
# mcap-ros2-support) that writes the ROS 2 bag the importer is tested on
# (host-sim/jointctl/tests/import_formats.rs), in the repository's ./.venv (shared with the other
# Python helpers; this only adds what these tests need). Idempotent: installs only what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv/bin/python ]; then
    python3 -m venv .venv
fi
if ! .venv/bin/python - <<'PY' 2>/dev/null
import can, canopen, pytest, serial, mcap, mcap_ros2
assert can.__version__.startswith("4."), can.__version__
assert canopen.__version__.startswith("2."), canopen.__version__
PY
then
    .venv/bin/pip install --quiet --disable-pip-version-check \
        "python-can>=4.4,<5" "canopen>=2.3,<3" "pyserial>=3.5,<4" "pytest>=7,<9" \
        "mcap>=1.1,<2" "mcap-ros2-support>=0.5,<1"
fi
.venv/bin/python -c "import can, canopen, pytest, mcap; print('python-can', can.__version__, 'canopen', canopen.__version__, 'pytest', pytest.__version__, 'mcap', mcap.__version__)"
