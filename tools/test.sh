#!/usr/bin/env bash
# The whole imufuse test suite, on a fresh clone: installs what it needs
# (the Debian cross toolchains and emulators for the MCU tests, the package
# with its test extras), then runs pytest. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
tools/install-toolchains.sh
"$PY" -m pip install -q --disable-pip-version-check -e ".[test]"
# the published-code oracle comes from PyPI, which the install above needs anyway:
# an unreachable oracle is a failure here, not a skip
export IMUFUSE_REQUIRE_ORACLE=1
exec "$PY" -m pytest "$@"
