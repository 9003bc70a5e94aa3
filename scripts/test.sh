#!/usr/bin/env bash
# Runs every test of the project: formatting, lints, the API docs, the firmware's thumb builds
# and sizes, the no-std dependency check, the kernels' instruction counts on the
# emulated Cortex-M3 (against the cost model), and the whole workspace's tests (among them 2x2x2 and 3x3x3 arrays
# of QEMU boards). Installs what it needs (thumb targets and llvm-tools through
# rustup, qemu-system-arm through apt-get) or says how.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n== %s\n' "$*"; }

THUMB=thumbv7m-none-eabi
for target in "$THUMB" thumbv7em-none-eabihf; do
    if ! rustup target list --installed 2>/dev/null | grep -qx "$target"; then
        step "installing the $target target"
        rustup target add "$target" || {
            echo "error: the $target target is missing and could not be installed; run: rustup target add $target" >&2
            exit 1
        }
    fi
done
if ! rustup component list --installed 2>/dev/null | grep -q '^llvm-tools'; then
    step "installing llvm-tools (firmware sizes)"
    rustup component add llvm-tools || {
        echo "error: llvm-tools is missing and could not be installed; run: rustup component add llvm-tools" >&2
        exit 1
    }
fi
if ! command -v qemu-system-arm >/dev/null; then
    step "installing qemu-system-arm (emulated boards)"
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq qemu-system-arm >/dev/null; } || {
        echo "error: qemu-system-arm is missing and could not be installed; run: apt-get install qemu-system-arm" >&2
        exit 1
    }
fi

step "format"
cargo fmt --all -- --check
cargo fmt --manifest-path firmware/Cargo.toml -- --check

step "lints (host, all targets)"
cargo clippy --workspace --all-targets --locked -- -D warnings

step "API docs build without warnings (broken links among them)"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked

step "lints and build of the no_std crates for $THUMB"
cargo clippy -p node-fw -p link-proto --target "$THUMB" --locked -- -D warnings
cargo build -p node-fw --target "$THUMB" --release --locked
(cd firmware && cargo clippy --release --locked --bins -- -D warnings)
# (stm32f413,interrupt-links: the F413 image with the emulated STM32's byte interrupts, its fallback.)
for board in stm32f413 stm32f413,interrupt-links netduinoplus2; do
    (cd firmware && cargo clippy --release --locked --bin node --no-default-features --features "$board" \
        --target thumbv7em-none-eabihf -- -D warnings)
done

step "node firmware: builds, sizes against the budget, kernel instruction counts on QEMU"
scripts/firmware.sh

step "node-fw's dependencies on $THUMB are all no_std"
scripts/check-no-std.sh "$THUMB"

step "the paper's experiments, reduced (lab bench paper --quick)"
cargo run --release --locked -p lab -- bench paper --quick --out target/paper-quick

step "efficiency and messaging share at S = 1, 8, 27 (lab bench scaling --quick)"
cargo run --release --locked -p lab -- bench scaling --quick --out target/scaling-quick

step "error against run time over the settings, reduced (lab report tradeoff --quick)"
cargo run --release --locked -p lab -- report tradeoff --quick --out target/tradeoff-quick

step "balancing modes over a camera orbit, reduced (lab bench animation --quick)"
cargo run --release --locked -p lab -- bench animation --quick --out target/animation-quick

step "tests"
cargo test --workspace --locked

# Release code is what benchmarks and boards run; a miscompile there
# (rust-lang/rust#158206 once dropped counted sends) shows only at opt-level >= 2.
step "the node fuzz tests again, optimised as release builds are"
cargo test --release --locked -p node-fw --test fuzz
