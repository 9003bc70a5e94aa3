#!/usr/bin/env bash
# Where a kernel's instructions go, function by function, on the emulated
# Cortex-M3: `hop_granted` (one end of a hop on a grant, the default),
# `trace` (a received ray's walk set-up), `sphere_hit` (a ray/sphere test
# that hits), `reply` (a short message's end), `shade` (a hit's surface and
# both its children, a shadow ray and a reflection) or
# `retire_batch` (retirements of six records, the host's end included, per
# message). Builds the `kernels` binary with the `profile` feature and PROFILE_KERNEL set (it then runs only that kernel),
# runs it under QEMU one instruction at a time (-singlestep -d exec), and sums
# the instructions each function executed from the kernel's entry on, per
# unit. Functions inlined into the kernel (for the hop, the reliable
# channel's send, transmit and receive) count as the kernel's own. Seconds;
# needs what scripts/firmware.sh needs, and python3. Not part of the test
# command: it measures, it checks nothing.
set -euo pipefail
cd "$(dirname "$0")/.."
KERNEL=${1:-hop_granted}
case "$KERNEL" in
    hop_granted) ENTRY=kernels::granted_hops ;;
    trace) ENTRY=kernels::walk_setups ;;
    sphere_hit) ENTRY=kernels::sphere_hits ;;
    reply) ENTRY=kernels::replies ;;
    shade) ENTRY=kernels::shadings ;;
    retire_batch) ENTRY=kernels::retirements ;;
    *) echo "error: no kernel $KERNEL to profile (hop_granted, trace, sphere_hit, reply or retire_batch)" >&2; exit 2 ;;
esac
command -v python3 >/dev/null || { echo "error: python3 is needed to sum the trace" >&2; exit 1; }

(cd firmware && PROFILE_KERNEL=$KERNEL cargo build --release --locked --bin kernels --features profile)
ELF=target/thumbv7m-none-eabi/release/kernels
NM="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin/llvm-nm"
[ -x "$NM" ] || { echo "error: llvm-nm missing; run: rustup component add llvm-tools" >&2; exit 1; }

WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
"$NM" -C --numeric-sort --print-size --defined-only "$ELF" >"$WORK/symbols"
mkfifo "$WORK/trace"
python3 - "$WORK/symbols" "$WORK/trace" "$ENTRY" >"$WORK/profile" <<'EOF' &
import bisect, collections, re, sys

symbols = []
for line in open(sys.argv[1]):
    parts = line.split(None, 3)
    if len(parts) == 4 and parts[2] in "tT":
        symbols.append((int(parts[0], 16) & ~1, int(parts[1], 16), re.sub(r"::h[0-9a-f]{16}$", "", parts[3].strip())))
symbols.sort()
starts = [s[0] for s in symbols]
entry = next(a for a, _, name in symbols if name == sys.argv[3])

def function(pc):
    i = bisect.bisect_right(starts, pc) - 1
    return symbols[i][2] if i >= 0 and pc < symbols[i][0] + symbols[i][1] else "?"

def pretty(name):
    return name.replace("$LT$", "<").replace("$GT$", ">").replace("$u20$", " ").replace("$RF$", "&")

# Library routines (memcpy, memclr) are charged to the function that called
# them: the last other function executing before them.
LIBRARY = re.compile(r"^(__aeabi_|compiler_builtins|mem)")
by_function, started, caller = collections.Counter(), False, "?"
pc_field = re.compile(r"/([0-9a-f]{8})/")
for line in open(sys.argv[2], errors="replace"):
    m = pc_field.search(line)
    if not m:
        continue
    pc = int(m.group(1), 16)
    started = started or pc == entry
    if not started:
        continue
    name = function(pc)
    if LIBRARY.match(name):
        name = f"{name} (from {caller})"
    else:
        caller = name
    by_function[pretty(name)] += 1
for name, n in by_function.most_common():
    print(n, name)
EOF
AGGREGATE=$!
OUT=$(timeout 900 qemu-system-arm -machine mps2-an385 -cpu cortex-m3 -nographic -icount shift=0 \
    -singlestep -d exec,nochain -D "$WORK/trace" -semihosting-config enable=on,target=native \
    -kernel "$ELF" </dev/null)
wait "$AGGREGATE"
# The kernel's line: per unit x 100, then the number of units.
UNITS=$(echo "$OUT" | awk -v k="$KERNEL" '$1 == "kernel" && $2 == k { print $4 }')
[ -n "$UNITS" ] || { echo "error: the kernel printed no result: $OUT" >&2; exit 1; }
echo "kernel $KERNEL on the emulated Cortex-M3 ($UNITS units), instructions per unit by function:"
awk -v units="$UNITS" '{ n = $1; $1 = ""; total += n; if (n / units >= 0.5) printf "  %8.1f %s\n", n / units, $0 }
    END { printf "  %8.1f in all (the timed loop included)\n", total / units }' "$WORK/profile"
