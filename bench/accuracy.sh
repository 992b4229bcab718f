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
# The MAGFit section is written by hand from bench/magfit.sh's run (its reading is prose);
# kept aside while the bench rewrites the file and put back at its end.
magfit_section="$(sed -n '/^## Autopilot compasses beside MAGFit/,$p' docs/ACCURACY.md 2>/dev/null || true)"
log "cargo bench --bench accuracy --profile bench-import (writes docs/ACCURACY.md)"
cargo bench --bench accuracy --profile bench-import
log "bench/attitude.sh (appends the attitude section to docs/ACCURACY.md)"
bench/attitude.sh >> docs/ACCURACY.md
if [ -n "$magfit_section" ]; then
  log "putting back the MAGFit section (bench/magfit.sh refreshes its figures)"
  printf '\n%s\n' "$magfit_section" >> docs/ACCURACY.md
fi
