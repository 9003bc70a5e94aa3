#!/usr/bin/env bash
# Builds the node firmware for the emulated mps2-an385 and the real STM32F413,
# prints their sizes against the budget (flash <= 128 KiB, RAM <= 64 KiB with
# at least 8 KiB of stack), and measures the kernels' instruction counts under
# QEMU (-icount shift=0). Needs the thumb targets, llvm-tools and
# qemu-system-arm; scripts/test.sh installs them.
set -euo pipefail
cd "$(dirname "$0")/.."

FLASH_BUDGET=$((128 * 1024))
RAM_BUDGET=$((64 * 1024))
STACK_MIN=$((8 * 1024))
SIZE="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin/llvm-size"
[ -x "$SIZE" ] || { echo "error: llvm-size missing; run: rustup component add llvm-tools" >&2; exit 1; }

check_size() {
    local name=$1 elf=$2
    # Berkeley format: text data bss.
    read -r text data bss _ < <("$SIZE" "$elf" | tail -1)
    local flash=$((text + data)) ram=$((data + bss))
    printf '%-28s flash %6d B (budget %d)   RAM %6d B static + %6d B stack (budget %d)\n' \
        "$name" "$flash" "$FLASH_BUDGET" "$ram" "$((RAM_BUDGET - ram))" "$RAM_BUDGET"
    if [ "$flash" -gt "$FLASH_BUDGET" ] || [ $((ram + STACK_MIN)) -gt "$RAM_BUDGET" ]; then
        echo "error: $name is over budget" >&2
        exit 1
    fi
}

(cd firmware && cargo build --release --locked --bins)
check_size "node (mps2-an385)" target/thumbv7m-none-eabi/release/node

(cd firmware && cargo build --release --locked --bin node --no-default-features --features stm32f413 \
    --target thumbv7em-none-eabihf)
check_size "node (stm32f413)" target/thumbv7em-none-eabihf/release/node

echo "kernels on the emulated Cortex-M3 (instructions, timed loops included):"
timeout 300 qemu-system-arm -machine mps2-an385 -cpu cortex-m3 -nographic -icount shift=0 \
    -semihosting-config enable=on,target=native \
    -kernel target/thumbv7m-none-eabi/release/kernels |
    awk '/^kernel / { printf "  %-12s %8.1f per unit over %d units\n", $2, $3 / 100, $4 }'
