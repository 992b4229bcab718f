# Idempotent installs shared by ./run and ./test (sourced, not run). Each function checks
# first and installs only what is missing or at the wrong version. Only the package
# registries are used: crates.io, Debian's apt, npm.

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

log() { printf '\033[1m==> %s\033[0m\n' "$*" >&2; }

as_root() {
  if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi
}

ensure_rust() {
  if ! command -v cargo >/dev/null 2>&1; then
    echo "cargo is missing: install Rust with rustup (https://rustup.rs) and run this again." >&2
    exit 1
  fi
  # ./test checks formatting and lints; rustup's minimal profile lacks both tools.
  local installed
  installed="$(rustup component list --installed 2>/dev/null || true)"
  for component in rustfmt clippy; do
    if ! grep -q "^$component" <<<"$installed"; then
      log "Adding the $component component"
      rustup component add "$component"
    fi
  done
}

ensure_wasm_target() {
  if ! rustup target list --installed 2>/dev/null | grep -qx wasm32-unknown-unknown; then
    log "Adding the wasm32-unknown-unknown target"
    rustup target add wasm32-unknown-unknown
  fi
}

# wasm-bindgen's CLI must match the wasm-bindgen crate in Cargo.lock exactly.
wasm_bindgen_version() {
  awk '/^name = "wasm-bindgen"$/ { getline; gsub(/version = |"/, ""); print; exit }' "$ROOT/Cargo.lock"
}

ensure_wasm_bindgen_cli() {
  local want
  want="$(wasm_bindgen_version)"
  if [ -z "$want" ]; then echo "no wasm-bindgen in Cargo.lock" >&2; exit 1; fi
  if [ "$(wasm-bindgen --version 2>/dev/null)" != "wasm-bindgen $want" ] \
     || [ "$(wasm-bindgen-test-runner --version 2>/dev/null)" != "wasm-bindgen-test-runner $want" ]; then
    log "Installing wasm-bindgen-cli $want (a few minutes, once)"
    # No --locked: one of its locked dependencies is no longer on crates.io.
    cargo install wasm-bindgen-cli --version "$want" --force --no-default-features \
      --bin wasm-bindgen --bin wasm-bindgen-test-runner
  fi
}

ensure_chromium() {
  if ! command -v chromium >/dev/null 2>&1 || ! command -v chromedriver >/dev/null 2>&1; then
    log "Installing Debian's chromium and chromium-driver"
    as_root apt-get update -qq
    as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null
  fi
}

ensure_e2e_packages() {
  local dir="$ROOT/tests/e2e"
  if [ ! -f "$dir/node_modules/.package-lock.json" ] \
     || [ "$dir/package-lock.json" -nt "$dir/node_modules/.package-lock.json" ]; then
    log "Installing the end-to-end test packages (npm ci)"
    npm ci --prefix "$dir" --no-audit --no-fund --loglevel=error
  fi
}

# Binaryen's optimiser over a wasm-bindgen module, in place, when the end-to-end packages
# (tests/e2e, which pin binaryen 132: Debian's 108 cannot read current modules) are
# installed; without it the module is left as built. -Os with `--converge` (the passes
# repeated while they shrink the module) and `--low-memory-unused` (constant addresses
# folded into loads and stores, since wasm-ld puts nothing below its global base of
# 1024). On the opt-level "s" module of 2026-11-27 (plain build), -Os gave 595,319 bytes
# gzipped against 598,410 for -O3 with the same two flags. (On the opt-level 3 modules
# before: -O3 611,763 on the threaded one, -O2 614,176, -Oz 610,716; on 2026-11-26 -O2
# and -Oz
# were the same size within 0.1 %.) The features are those the modules are built with
# (Rust's wasm32 defaults, and threads and SIMD for the threaded one); Chromium runs
# them all.
# -O1, not -Os: on 2026-12-05 binaryen's -Os and -O2 made both modules smaller raw but
# larger gzipped (plain 589,900 against 558,899 bytes with -O1; threaded 610,598 against
# 590,763), and the page's drops take the same time (BENCHMARKS.md, "wasm-opt -O1").
optimise_wasm() {
  local wasm="$1"
  local wasm_opt="$ROOT/tests/e2e/node_modules/.bin/wasm-opt"
  if [ ! -x "$wasm_opt" ]; then
    log "No tests/e2e/node_modules/.bin/wasm-opt (npm ci --prefix tests/e2e): $(basename "$wasm") left unoptimised"
    return 0
  fi
  # KEEP_WASM_NAMES=1 keeps the functions' names, for profiles
  # (bench/first_drop_compiles.mjs); the sizes are then not the page's.
  "$wasm_opt" -O1 ${KEEP_WASM_NAMES:+-g} --converge --low-memory-unused --enable-threads --enable-bulk-memory --enable-mutable-globals --enable-simd \
    --enable-sign-ext --enable-nontrapping-float-to-int --enable-reference-types --enable-multivalue \
    "$wasm" -o "$wasm.opt" && mv "$wasm.opt" "$wasm"
}

# The page's two modules (docs/development.md, "Size of the page"):
# - www/pkg, the first-paint module every browser can load (one thread), is built for
#   size ("z"; measured on one build of the same code, 2026-11-27: 3 gave 650,404 bytes
#   gzipped, "s" 595,319 and "z" 541,192) and must stay within 600,000 bytes gzipped;
# - www/pkg-threads, the analysis module a cross-origin isolated page and its workers
#   run on shared memory (issue 45), is built for speed (opt-level 3) within 1,200,000:
#   on 2026-12-06 its drops took 0.50-0.88x the time of the size-built module on every
#   shared recording (docs/BENCHMARKS.md), and the demo's first render was no slower.
export COMPASS_PDR_WASM_OPT_LEVEL="${COMPASS_PDR_WASM_OPT_LEVEL:-z}"
export COMPASS_PDR_WASM_THREADS_OPT_LEVEL="${COMPASS_PDR_WASM_THREADS_OPT_LEVEL:-3}"

# Builds the release wasm, generates its JS glue into www/pkg and puts the demo log
# beside it, so that www/ is the whole static site.
build_web() {
  log "Building the page (release wasm)"
  CARGO_PROFILE_RELEASE_OPT_LEVEL="$COMPASS_PDR_WASM_OPT_LEVEL" \
    cargo build --manifest-path "$ROOT/Cargo.toml" --release --lib --target wasm32-unknown-unknown
  rm -rf "$ROOT/www/pkg"
  # Without the function names (177 KB raw, 53 KB gzipped of the module): a panic's
  # message still reaches the page (console_error_panic_hook), its stack shows indices.
  wasm-bindgen --target web --no-typescript --remove-name-section --remove-producers-section \
    --out-dir "$ROOT/www/pkg" "$ROOT/target/wasm32-unknown-unknown/release/compass_pdr.wasm"
  cp "$ROOT/assets/demo-walk.csv" "$ROOT/www/pkg/demo-walk.csv"
  local wasm="$ROOT/www/pkg/compass_pdr_bg.wasm"
  optimise_wasm "$wasm"
  log "wasm size: $(stat -c %s "$wasm") bytes raw, $(gzip -9 -c "$wasm" | wc -c) bytes gzip -9"
}

# The threaded module (www/pkg-threads) is built by a nightly compiler: WebAssembly
# threads need the standard library rebuilt with atomics (-Z build-std), which stable
# Rust cannot do. The page loads it when the browser allows shared memory (a
# cross-origin isolated page) and otherwise uses www/pkg. Returns non-zero, with a
# message, when no nightly with rust-src can be had: the page then runs on one thread.
ensure_nightly() {
  if rustup run nightly rustc --version >/dev/null 2>&1 \
     && rustup component list --toolchain nightly --installed 2>/dev/null | grep -q '^rust-src'; then
    return 0
  fi
  log "Installing a nightly Rust with rust-src (for the threaded module, once)"
  rustup toolchain install nightly --profile minimal --component rust-src --target wasm32-unknown-unknown
}

# The analysis module keeps the panic machinery and Debug formatting (a panic reaches
# the page with its message, through the panic hook): from 2026-11-27 to 2026-12-06 it
# was built without them (-Zlocation-detail=none -Zfmt-debug=none
# -Cpanic=immediate-abort, inline threshold 25) to fit a 614,400-byte budget; with its
# own budget they cost 24 kB gzipped (731,400 -> 755,764 bytes) and no time measurable
# in the page's drops (bench/drop_costs.mjs, two alternating rounds).
THREADS_RUSTFLAGS="--cfg=web_sys_unstable_apis \
-C target-feature=+atomics,+bulk-memory,+mutable-globals,+simd128 \
-C link-arg=--shared-memory -C link-arg=--import-memory -C link-arg=--max-memory=4294967296 \
-C link-arg=--export=__wasm_init_tls -C link-arg=--export=__tls_size \
-C link-arg=--export=__tls_align -C link-arg=--export=__tls_base"

# Builds the threaded module into OUT_DIR (default www/pkg-threads; see ensure_nightly),
# with the crate's FEATURES (comma-separated; bench/run asks for import-bench).
build_web_threads() {
  local out_dir="${1:-$ROOT/www/pkg-threads}" features="${2:-}"
  if ! ensure_nightly; then
    log "No nightly Rust: the page will read files on one thread"
    rm -rf "$out_dir"
    return 1
  fi
  log "Building the threaded page module (release wasm, nightly, shared memory)"
  # Checked step by step: a caller may run this with errexit off (`./run` goes on
  # without threads), and a failed build must not leave an older module in place.
  rm -rf "$out_dir"
  if ! RUSTFLAGS="$THREADS_RUSTFLAGS" CARGO_PROFILE_RELEASE_OPT_LEVEL="$COMPASS_PDR_WASM_THREADS_OPT_LEVEL" cargo +nightly build --manifest-path "$ROOT/Cargo.toml" \
      --release --lib --target wasm32-unknown-unknown -Z build-std=std,panic_abort \
      --features "$features" --target-dir "$ROOT/target/threads" \
    || ! wasm-bindgen --target web --no-typescript $([ -n "${KEEP_WASM_NAMES:-}" ] || echo --remove-name-section) \
      --remove-producers-section --out-dir "$out_dir" \
      "$ROOT/target/threads/wasm32-unknown-unknown/release/compass_pdr.wasm"; then
    log "The threaded module did not build: the page will read files on one thread"
    rm -rf "$out_dir"
    return 1
  fi
  copy_warm_up "$out_dir/warm-up"
  local wasm="$out_dir/compass_pdr_bg.wasm"
  optimise_wasm "$wasm"
  log "threaded wasm size: $(stat -c %s "$wasm") bytes raw, $(gzip -9 -c "$wasm" | wc -c) bytes gzip -9"
}

# The small logs the analysis worker analyses while the user picks a file
# (www/analysis-worker.js, warmUp): one of each format the page reads, from tests/data
# (generated by tests/data/formats.py and the simulator), listed in warm-up.json, each
# entry one recording's files.
WARM_UP_LOGS=(flight-trim.bin walk.ulg getsensordata-walk.txt indoor-walk.txt tyrex-walk walk.nmea
  dance.txt plotter.txt Magnetometer.csv sensorlogger-walk)
copy_warm_up() {
  local dir="$1" entries=() name file files
  mkdir -p "$dir"
  for name in "${WARM_UP_LOGS[@]}"; do
    cp -r "$ROOT/tests/data/$name" "$dir/"
    if [ -d "$ROOT/tests/data/$name" ]; then
      files=""
      for file in "$ROOT/tests/data/$name"/*; do files+="${files:+, }\"$name/$(basename "$file")\""; done
      entries+=("[$files]")
    else
      entries+=("[\"$name\"]")
    fi
  done
  local IFS=,
  printf '[%s]\n' "${entries[*]}" > "$dir/warm-up.json"
}

# Waits until a local URL answers, for at most 20 s.
wait_for_url() {
  local url="$1"
  for _ in $(seq 1 100); do
    if python3 -c "import sys, urllib.request; urllib.request.urlopen(sys.argv[1], timeout=2)" "$url" 2>/dev/null; then
      return 0
    fi
    sleep 0.2
  done
  echo "the server at $url did not answer" >&2
  return 1
}
