#!/usr/bin/env bash
# Fails if node-fw's dependency tree for the given target holds a crate outside
# the reviewed no_std list. Building for a thumb target already proves that
# nothing links std; this catches a new dependency before anyone relies on it.
# thiserror 2 arrives through cobs with its "std" feature off (no_std).
set -euo pipefail
target=${1:-thumbv7m-none-eabi}
allowed=" node-fw link-proto heapless hash32 byteorder stable_deref_trait fixed az bytemuck half cfg-if zerocopy typenum postcard serde serde_core cobs crc crc-catalog thiserror "
bad=0
while read -r name; do
    [ -z "$name" ] && continue
    if [[ "$allowed" != *" $name "* ]]; then
        echo "error: node-fw on $target depends on '$name', which is not on the reviewed no_std list in $0" >&2
        bad=1
    fi
done < <(cargo tree -p node-fw --target "$target" -e normal,no-proc-macro --prefix none --format '{p}' --locked \
    | awk '{print $1}' | sort -u)
[ "$bad" = 0 ] && echo "ok: every dependency of node-fw on $target is on the no_std list"
exit "$bad"
