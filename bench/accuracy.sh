#!/usr/bin/env bash
# The accuracy report: heading and PDR accuracy on the simulator's scenarios and
# on the real recordings in ../shared/data, beside the papers' numbers. Writes
# docs/ACCURACY.md (benches/accuracy.rs). Takes about a minute; not part of ./test.
#
#   bench/accuracy.sh
set -euo pipefail
source "$(dirname "$0")/../scripts/setup.sh"
cd "$ROOT"
ensure_rust
# The sections written by hand (issue 43's motions, the attitude filter's σ and settings,
# MAGFit, the IPIN walks) follow a marker line in docs/ACCURACY.md; kept aside while the
# bench rewrites the file and put back at its end, as they are.
marker='<!-- Written by hand below this line'
kept_by_hand="$(sed -n "/^${marker}/,\$p" docs/ACCURACY.md 2>/dev/null || true)"
log "cargo bench --bench accuracy --profile bench-import (writes docs/ACCURACY.md)"
cargo bench --bench accuracy --profile bench-import
log "bench/attitude.sh (appends the attitude section to docs/ACCURACY.md)"
bench/attitude.sh >> docs/ACCURACY.md
if [ -n "$kept_by_hand" ]; then
  log "putting back the sections written by hand (each names the command of its figures)"
  printf '\n%s\n' "$kept_by_hand" >> docs/ACCURACY.md
else
  log "no '${marker}' line in docs/ACCURACY.md: nothing written by hand was kept"
fi
