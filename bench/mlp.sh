#!/usr/bin/env bash
# The MLP-training benchmark in one go: compass-pdr's L-BFGS training on
# 10,000 samples (5 inputs, 15 logistic neurons) natively (criterion, benches/mlp.rs,
# which also writes the samples), scikit-learn's MLPRegressor(solver="lbfgs") on the
# same samples with the same architecture, loss and stopping rules (bench/mlp_peer.py),
# and the same training in WebAssembly in headless Chromium (bench/wasm/mlp.html).
# Prints one table; raw results in target/bench-results/mlp-*. Idempotent (the venv and
# the builds are reused). Not part of ./test; bench/run may call it.
#
#   bench/mlp.sh
set -euo pipefail
source "$(dirname "$0")/../scripts/setup.sh"
cd "$ROOT"
results="$ROOT/target/bench-results"
data="$ROOT/target/bench-data"
mkdir -p "$results"
run_tmp="$(mktemp -d)"
trap 'rm -rf "$run_tmp"' EXIT

ensure_wasm_target
ensure_wasm_bindgen_cli
ensure_chromium
ensure_e2e_packages

log "Python peer: venv at target/bench-venv with scikit-learn"
venv="$ROOT/target/bench-venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check scikit-learn

load_native="$(cut -d' ' -f1-3 /proc/loadavg)"
log "Native: cargo bench --bench mlp (writes target/bench-data/mlp_*)"
cargo bench --bench mlp --profile bench-import 2>&1 | tee "$results/criterion-mlp.log"

load_peer="$(cut -d' ' -f1-3 /proc/loadavg)"
log "Peer: bench/mlp_peer.py (scikit-learn MLPRegressor, lbfgs)"
"$venv/bin/python" bench/mlp_peer.py "$data" > "$results/mlp_peer.json"

log "WebAssembly: release module into target/bench-wasm/pkg, bench/wasm/mlp.html in headless Chromium"
cargo build --release --lib --target wasm32-unknown-unknown
rm -rf "$ROOT/target/bench-wasm/pkg"
wasm-bindgen --target web --no-typescript --out-dir "$ROOT/target/bench-wasm/pkg" \
  "$ROOT/target/wasm32-unknown-unknown/release/compass_pdr.wasm"
load_wasm="$(cut -d' ' -f1-3 /proc/loadavg)"
TMPDIR="$run_tmp" XDG_CONFIG_HOME="$run_tmp/config" XDG_CACHE_HOME="$run_tmp/cache" \
  node bench/wasm-bench.mjs --runs 5 --page mlp.html > "$results/wasm-mlp.json"

BENCH_LOAD_NATIVE="$load_native" BENCH_LOAD_PEER="$load_peer" BENCH_LOAD_WASM="$load_wasm" \
python3 - "$ROOT" <<'PY'
import json, os, sys

root = sys.argv[1]
env = os.environ


def load(*parts):
    with open(os.path.join(root, "target", *parts)) as file:
        return json.load(file)


settings = load("bench-data", "mlp_settings.json")
native = load("bench-data", "mlp_native.json")
estimates = load("criterion", "mlp", f"lbfgs_{settings['n_train']}", "new", "estimates.json")
peer = load("bench-results", "mlp_peer.json")
wasm = load("bench-results", "wasm-mlp.json")

native_ms = estimates["median"]["point_estimate"] / 1e6
ci = estimates["median"]["confidence_interval"]
wasm_ms = wasm["median_ms"]
peer_ms = peer["median_s"] * 1e3
print()
print(f"MLP training: {settings['n_train']:,} samples, {settings['n_inputs']} inputs, "
      f"{settings['hidden']} {settings['activation']} neurons, L-BFGS, alpha {settings['alpha']}, "
      f"at most {settings['max_iter']} iterations, gradient tolerance {settings['tol']}; "
      f"test set {settings['n_test']:,} samples")
print()
print("| run | median ms | iterations | train MSE (deg²) | test MSE (deg²) | sklearn time / this | load (1, 5, 15 min) at start |")
print("|---|---|---|---|---|---|---|")
print(f"| ours, native (criterion, 95% CI {ci['lower_bound'] / 1e6:.0f}-{ci['upper_bound'] / 1e6:.0f}) "
      f"| {native_ms:.0f} | {native['iterations']} | {native['train_mse']:.5f} | {native['test_mse']:.5f} "
      f"| {peer_ms / native_ms:.1f}x | {env['BENCH_LOAD_NATIVE']} |")
print(f"| ours, wasm (Chromium {wasm['chromium']}, {wasm['runs']} runs) | {wasm_ms:.0f} | {wasm['iterations']} "
      f"| {wasm['train_mse']:.5f} | {wasm['test_mse']:.5f} | {peer_ms / wasm_ms:.1f}x | {env['BENCH_LOAD_WASM']} |")
print(f"| scikit-learn {peer['sklearn']} MLPRegressor lbfgs ({peer['runs']} runs) | {peer_ms:.0f} | {peer['n_iter']} "
      f"| {peer['train_mse']:.5f} | {peer['test_mse']:.5f} | 1.0x | {env['BENCH_LOAD_PEER']} |")
print()
print(f"Ours, native, spreads each gradient over the cores ({os.cpu_count()} here; batches of 4,096 samples "
      f"or more, in parts of 1,024 whose sums are added in a fixed order, so the weights do not depend on the "
      f"number of cores); wasm runs on one thread. Ours evaluates the network in single precision (eight "
      f"f32 lanes, sums over each 128 samples added in f64; the L-BFGS state is f64), scikit-learn in double; "
      f"the MSE columns compare the results. scikit-learn uses whatever threads its numpy BLAS takes.")
print()
ok_native = peer_ms / native_ms >= 10 and native["test_mse"] <= peer["test_mse"]
ok_wasm = wasm_ms < 1000
print(f"- native at least 10x faster than scikit-learn at equal or lower test MSE: {'met' if ok_native else 'NOT met'}")
print(f"- wasm under 1 s: {'met' if ok_wasm else 'NOT met'}")
PY
