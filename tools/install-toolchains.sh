#!/bin/sh
# Install the Debian packages the test suite needs beyond Python: the cross
# toolchains and emulators of the MCU harness (python/imufuse/mcu), valgrind,
# make (library builds) and g++ (the published-code oracle), on Debian 12. Idempotent: packages already present are
# left alone, and apt is only touched when something is missing.
#
# Usage: tools/install-toolchains.sh [--check]
#   --check   only report what is missing; exit 1 if anything is.
# Must run as root (or with sudo available) to install.
set -eu

# clang + libclang-rt-14-dev: the sanitizer and libFuzzer runs of tests/test_sanitizers.py
# gcc-riscv64-unknown-elf + picolibc-riscv64-unknown-elf + qemu-system-misc: the RV32 targets
# (rv32imac, rv32imafc on qemu-system-riscv32 -M virt)
PACKAGES="make g++ pkg-config arduino-builder arduino-core-avr gcc-arm-none-eabi libnewlib-arm-none-eabi libstdc++-arm-none-eabi-newlib qemu-system-arm gcc-avr avr-libc binutils-avr simavr libsimavr-dev valgrind clang libclang-rt-14-dev gcc-riscv64-unknown-elf picolibc-riscv64-unknown-elf qemu-system-misc"

missing=""
for p in $PACKAGES; do
    if dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        echo "install-toolchains: $p already installed"
    else
        missing="$missing $p"
    fi
done

if [ -z "$missing" ]; then
    echo "install-toolchains: nothing to install"
    exit 0
fi

echo "install-toolchains: missing:$missing"
if [ "${1:-}" = "--check" ]; then
    exit 1
fi

SUDO=""
if [ "$(id -u)" != "0" ]; then
    if command -v sudo >/dev/null 2>&1; then
        SUDO="sudo"
    else
        echo "install-toolchains: not root and no sudo; cannot install:$missing" >&2
        exit 2
    fi
fi

export DEBIAN_FRONTEND=noninteractive
echo "install-toolchains: apt-get update"
$SUDO apt-get update
echo "install-toolchains: apt-get install -y --no-install-recommends$missing"
# shellcheck disable=SC2086
$SUDO apt-get install -y --no-install-recommends $missing
echo "install-toolchains: done"
