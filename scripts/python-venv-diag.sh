#!/usr/bin/env bash
# NumPy/SciPy for the diagnosis speed comparison (tests/python/bench_numpy_diagnose.py), in the
# repository's ./.venv (shared with the other Python helpers; only adds what diagnose needs).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv/bin/python ]; then
    python3 -m venv .venv
fi
.venv/bin/pip install --quiet --disable-pip-version-check "numpy>=1.24" "scipy>=1.10"
.venv/bin/python -c "import numpy, scipy; print('numpy', numpy.__version__, 'scipy', scipy.__version__)"
