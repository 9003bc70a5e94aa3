#!/usr/bin/env bash
# Builds the node firmware for the emulated mps2-an385 (the small-MCU profile:
# 128 KiB of flash, 64 KiB of RAM), the NUCLEO-F413ZH and QEMU's netduinoplus2
# (the same STM32 code with the emulated SoC's smaller RAM), copies each image
# to target/firmware/node-<board>.elf, prints its sizes against its chip (at
# least 8 KiB of RAM left for the stack), and measures the kernels' instruction counts under
# QEMU (-icount shift=0), failing when the in-memory board's cost model is more
# than 2% off any of them. Needs the thumb targets, llvm-tools and
# qemu-system-arm; scripts/test.sh installs them.
set -euo pipefail
cd "$(dirname "$0")/.."

STACK_MIN=$((8 * 1024))
OUT=target/firmware
mkdir -p "$OUT"
SIZE="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin/llvm-size"
[ -x "$SIZE" ] || { echo "error: llvm-size missing; run: rustup component add llvm-tools" >&2; exit 1; }
for target in thumbv7m-none-eabi thumbv7em-none-eabihf; do
    rustup target list --installed 2>/dev/null | grep -qx "$target" ||
        { echo "error: the $target target is missing; run: rustup target add $target" >&2; exit 1; }
done
command -v qemu-system-arm >/dev/null ||
    { echo "error: qemu-system-arm missing; run: apt-get install qemu-system-arm" >&2; exit 1; }

# check_size BOARD ELF FLASH_KIB RAM_KIB: copies the image to $OUT and checks it fits.
check_size() {
    local board=$1 elf=$2 flash_budget=$(($3 * 1024)) ram_budget=$(($4 * 1024))
    # Berkeley format: text data bss.
    read -r text data bss _ < <("$SIZE" "$elf" | tail -1)
    local flash=$((text + data)) ram=$((data + bss))
    printf '%-16s flash %7d B of %7d   RAM %6d B static + %6d B stack of %6d\n' \
        "$board" "$flash" "$flash_budget" "$ram" "$((ram_budget - ram))" "$ram_budget"
    if [ "$flash" -gt "$flash_budget" ] || [ $((ram + STACK_MIN)) -gt "$ram_budget" ]; then
        echo "error: the $board image is over its chip's budget" >&2
        exit 1
    fi
    cp "$elf" "$OUT/node-$board.elf"
}

(cd firmware && cargo build --release --locked --bins)
check_size mps2-an385 target/thumbv7m-none-eabi/release/node 128 64
# The node's and the channels' statics are built all zeros so that they take no flash (node.rs):
# a non-zero initial value would move all of it into `.data`, copied from flash.
NM="$(dirname "$SIZE")/llvm-nm"
# (grep without -q reads all of nm's output: under pipefail, nm cut off by an
# early exit would fail the pipe.)
for static in LINKS NODE; do
    "$NM" "$OUT/node-mps2-an385.elf" | grep " [bB] .*node${#static}$static" >/dev/null || {
        echo "error: the node's $static static is not zero-initialised: its initial values take flash" >&2
        exit 1
    }
done
# A firmware that panics on purpose: the emulated tests check that its last words reach the host.
cp target/thumbv7m-none-eabi/release/fault_check "$OUT/fault-check-mps2-an385.elf"

for board in stm32f413:1536:320 netduinoplus2:1024:192; do
    IFS=: read -r name flash ram <<<"$board"
    (cd firmware && cargo build --release --locked --bin node --no-default-features --features "$name" \
        --target thumbv7em-none-eabihf)
    check_size "$name" target/thumbv7em-none-eabihf/release/node "$flash" "$ram"
done
# The real board logs over RTT: its image must carry the RTT control block and defmt's strings.
grep -q _SEGGER_RTT "$OUT/node-stm32f413.elf" && "$SIZE" -A "$OUT/node-stm32f413.elf" | grep '^\.defmt' >/dev/null || {
    echo "error: the stm32f413 image has no defmt log over RTT" >&2
    exit 1
}
# The in-memory board's `f413` links charge each frame the path of a DMA send
# stream's handler, counted in the stm32f413 image, and `--transfer interrupt`
# each byte the path of a UART's interrupt handler, counted in the
# netduinoplus2 image, which moves every byte so with the same code as the
# stm32f413 image built with `interrupt-links` (sim-board/src/link_spec.rs: 32
# instructions for a byte received, 25 for one sent, of a handler of 51; 43 to
# 48 for a run sent and the next started). A handler that grows, or takes a loop, a
# call or (the UART's) a barrier, must be counted afresh and the charge
# changed. (awk reads all of objdump's output: see nm's above.)
OBJDUMP="$(dirname "$SIZE")/llvm-objdump"
# Each image disassembled once.
declare -A DISASSEMBLY
for image in stm32f413 netduinoplus2; do
    DISASSEMBLY[$image]=$("$OBJDUMP" -d --no-show-raw-insn "$OUT/node-$image.elf")
done
# check_handler IMAGE NAME MAX_INSTRUCTIONS MAX_DMB WHAT
check_handler() {
    local image=$1 name=$2 most=$3 barriers=$4 charge=$5 body len calls
    body=$(echo "${DISASSEMBLY[$image]}" | awk "/<$name>:/ { on = 1; next } /^\$/ { on = 0 } on")
    len=$(echo "$body" | grep -c .)
    # A branch or call to any other symbol means part of the path lies
    # outside the handler, where this count does not see it.
    calls=$(echo "$body" | grep -E '<[^>]+>' | grep -cv "<$name+" || true)
    if [ "$len" -eq 0 ] || [ "$len" -gt "$most" ] || [ "$calls" -gt 0 ] ||
        [ "$(echo "$body" | grep -cw dmb || true)" -gt "$barriers" ]; then
        echo "error: the $image $name handler has $len instructions and $calls calls out" \
            "(at most $most, none, $barriers dmb): count its paths again and update $charge" >&2
        exit 1
    fi
    echo "$image $name handler: $len instructions"
}
check_handler netduinoplus2 USART3 51 0 Transfer::cycles_per_byte
# Every link's send stream: +X, -X, +Y, -Y, +Z, -Z and the host's.
for stream in DMA2_STREAM7 DMA1_STREAM6 DMA1_STREAM4 DMA1_STREAM7 DMA2_STREAM6 DMA2_STREAM5 DMA1_STREAM3; do
    check_handler stm32f413 "$stream" 48 1 Transfer::cycles_per_frame
done

echo "kernels on the emulated Cortex-M3 (instructions, timed loops included):"
KERNELS=$(timeout 300 qemu-system-arm -machine mps2-an385 -cpu cortex-m3 -nographic -icount shift=0 \
    -semihosting-config enable=on,target=native \
    -kernel target/thumbv7m-none-eabi/release/kernels)
echo "$KERNELS" | awk '/^kernel / { printf "  %-12s %8.1f per unit over %d units\n", $2, $3 / 100, $4 }'

# The in-memory board charges these costs (sim-board/src/cost.rs): a change to
# the firmware that moves a kernel by more than 2% must update them, or every
# simulated makespan would describe firmware that no longer exists.
# The default model's value of field $1 (only inside `fn default`: tests build models of their own).
model() {
    local v
    v=$(sed -n "/fn default() -> Self {/,/^    }$/ s/^ *$1: \([0-9_]*\),$/\1/p" sim-board/src/cost.rs | tr -d _)
    [[ "$v" =~ ^[0-9]+$ ]] || { echo "error: no single default for $1 in sim-board/src/cost.rs" >&2; exit 1; }
    echo "$v"
}
check_cost() {
    local kernel=$1 charged=$2
    local measured
    measured=$(echo "$KERNELS" | awk -v k="$kernel" '$1 == "kernel" && $2 == k { print $3 / 100 }')
    [ -n "$measured" ] || { echo "error: kernel $kernel not measured" >&2; exit 1; }
    if ! awk -v m="$measured" -v c="$charged" 'BEGIN { d = (m - c) / c; exit !(d <= 0.02 && d >= -0.02) }'; then
        echo "error: kernel $kernel measures $measured instructions, the cost model charges $charged:" \
            "update sim-board/src/cost.rs" >&2
        exit 1
    fi
}
check_cost cube_walk "$(model cube_step)"
check_cost clear_walk "$(model clear_step)"
check_cost clear_look "$(model clear_look)"
check_cost ignore_look "$(model ignore_look)"
check_cost map_take "$(model map_take)"
check_cost sphere_test "$(model sphere_test)"
check_cost sphere_hit "$(($(model sphere_test) + $(model sphere_hit)))"
check_cost trace "$(model trace)"
check_cost shade "$(model shade)"
check_cost create "$(model create)"
check_cost reply "$(model short_message)"
check_cost hop "$(($(model ray_message) + $(model short_message)))"
check_cost hop_granted "$(model granted_ray)"
check_cost hop_batched "$(model batched_ray)"
check_cost retire "$(model retire_message)"
# A retirement message with six records (the kernels' RETIRE_BATCH).
check_cost retire_batch "$(($(model retire_message) + 5 * $(model retire_record)))"
echo "cost model (sim-board/src/cost.rs) within 2% of every kernel"
