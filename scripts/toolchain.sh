#!/usr/bin/env bash
# Install the Cortex-M cross toolchain, QEMU, clang (the kernel is checked with gcc and
# clang; clang's libFuzzer runs make fuzz), cmake (firmware/c/CMakeLists.txt, the imu3
# example) and cppcheck (make misra: its MISRA C:2012 addon) when missing (Debian, root only).
set -u
need=()
command -v arm-none-eabi-gcc >/dev/null 2>&1 || need+=(gcc-arm-none-eabi)
[ -e /usr/lib/arm-none-eabi/newlib ] || [ -e /usr/lib/arm-none-eabi/lib ] || need+=(libnewlib-arm-none-eabi)
command -v qemu-system-arm >/dev/null 2>&1 || need+=(qemu-system-arm)
command -v clang >/dev/null 2>&1 || need+=(clang)
command -v cmake >/dev/null 2>&1 || need+=(cmake)
command -v cppcheck >/dev/null 2>&1 || need+=(cppcheck)
# fogsf fleet's tests: a PostgreSQL server they start, Chromium that renders its report
ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || need+=(postgresql)
command -v chromium >/dev/null 2>&1 || need+=(chromium)
if [ ${#need[@]} -eq 0 ]; then
    echo "toolchain: arm-none-eabi-gcc, qemu-system-arm, clang, cmake, cppcheck, postgresql and chromium present"
    exit 0
fi
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then
    echo "toolchain: skipped (need root and apt-get to install: ${need[*]}); Cortex-M4F checks will be skipped"
    exit 0
fi
echo "toolchain: installing ${need[*]}"
export DEBIAN_FRONTEND=noninteractive
apt-get update -qq && apt-get install -y -qq "${need[@]}" >/dev/null
command -v arm-none-eabi-gcc >/dev/null && command -v qemu-system-arm >/dev/null \
    && echo "toolchain: installed" || { echo "toolchain: install failed"; exit 1; }
