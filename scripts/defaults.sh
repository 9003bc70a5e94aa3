#!/usr/bin/env bash
# Measures the render defaults against the alternatives a user can pick:
# the slide policy (paper or proportional) and the starting layout (even or
# preview), on the default link (f413) and the ideal one, over four scenes.
# Prints a Markdown table of makespans (virtual cycles of the in-memory
# board); docs/partition-and-sliding.md shows its output. About a minute.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -q -p host-tool
BIN=target/release/host-tool
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
makespan() { "$BIN" render "$@" --out-dir "$OUT/$RANDOM$RANDOM" 2>&1 | sed -n 's/.*makespan \([0-9]*\) cycles.*/\1/p'; }
echo "| scene | link | even, paper | even, proportional | preview, proportional |"
echo "|---|---|---|---|---|"
for scene in "demo (400 spheres, seed 1986)|" "1000 spheres, seed 7|--spheres 1000 --seed 7" \
    "1000 spheres, seed 1986, volume 1/4|--spheres 1000 --seed 1986 --volume-ratio 0.25" \
    "400 spheres, seed 3, 2x2x2|--spheres 400 --seed 3 --array 2x2x2"; do
    IFS='|' read -r name args <<<"$scene"
    for link in f413 ideal; do
        # shellcheck disable=SC2086
        a=$(makespan $args --link "$link" --policy paper)
        # shellcheck disable=SC2086
        b=$(makespan $args --link "$link" --policy proportional)
        # shellcheck disable=SC2086
        c=$(makespan $args --link "$link" --policy proportional --layout preview --driving-axis view)
        printf '| %s | %s | %.3g | %.3g | %.3g |\n' "$name" "$link" "$a" "$b" "$c"
    done
done
