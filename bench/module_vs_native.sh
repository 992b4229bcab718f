#!/usr/bin/env bash
# The page's analysis without the page, against the native CLI on one core (see
# bench/module_vs_native.mjs): builds the module as the page's threaded one is
# optimised (opt-level 3, the analysis module), for Node, and the release CLI. Not part
# of ./test.
#
#   bench/module_vs_native.sh [runs]
set -euo pipefail
source "$(dirname "$0")/../scripts/setup.sh"
cd "$ROOT"
ensure_wasm_target
ensure_wasm_bindgen_cli
log "Building the module for Node (opt-level 3) and the release CLI"
CARGO_PROFILE_RELEASE_OPT_LEVEL=3 cargo build --quiet --release --lib --target wasm32-unknown-unknown \
  --target-dir "$ROOT/target/bench-node"
wasm-bindgen --target nodejs --no-typescript --out-dir "$ROOT/target/bench-node/pkg" \
  "$ROOT/target/bench-node/wasm32-unknown-unknown/release/compass_pdr.wasm"
cargo build --quiet --release --bin compass-pdr
node "$ROOT/bench/module_vs_native.mjs" "$ROOT/target/bench-node/pkg" "$ROOT/target/release/compass-pdr" "${1:-7}"
