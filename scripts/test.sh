#!/usr/bin/env bash
# Runs every test of the project: formatting, lints, the firmware's thumb build,
# the no-std dependency check, and the whole workspace's tests.
# Installs what it needs (the thumbv7m target through rustup) or says how.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n== %s\n' "$*"; }

THUMB=thumbv7m-none-eabi
if ! rustup target list --installed 2>/dev/null | grep -qx "$THUMB"; then
    step "installing the $THUMB target"
    rustup target add "$THUMB" || {
        echo "error: the $THUMB target is missing and could not be installed; run: rustup target add $THUMB" >&2
        exit 1
    }
fi

step "format"
cargo fmt --all -- --check

step "lints (host, all targets)"
cargo clippy --workspace --all-targets --locked -- -D warnings

step "lints and build of the no_std crates for $THUMB"
cargo clippy -p node-fw -p link-proto --target "$THUMB" --locked -- -D warnings
cargo build -p node-fw --target "$THUMB" --release --locked

step "node-fw's dependencies on $THUMB are all no_std"
scripts/check-no-std.sh "$THUMB"

step "the paper's experiments, reduced (host-tool bench paper --quick)"
cargo run --release --locked -p host-tool -- bench paper --quick --out target/paper-quick

step "error against run time of the arithmetic variants, reduced (host-tool report numerics --quick)"
cargo run --release --locked -p host-tool -- report numerics --quick --out target/numerics-quick

step "tests"
cargo test --workspace --locked
