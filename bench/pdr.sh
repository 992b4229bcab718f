#!/usr/bin/env bash
# The PDR benchmark in one go: compass-pdr's [E, N, l, a] EKF in steps per
# second natively (criterion, benches/pdr.rs, which also writes the inputs), the same
# filter with filterpy's ExtendedKalmanFilter and as a plain numpy loop on the same steps
# (bench/pdr_peer.py), and in WebAssembly in headless Chromium (bench/wasm/pdr.html);
# and the whole pipeline (import, calibrations and heading models, steps, step model,
# EKF, metrics) on a simulated hour at 100 Hz natively and in WebAssembly, with the
# native time of each stage. Prints one table; raw results in target/bench-results/pdr-*
# and target/bench-data/pdr_*. Idempotent (the venv and the builds are reused). Not part
# of ./test; bench/run calls it.
#
#   bench/pdr.sh
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

log "Python peers: venv at target/bench-venv with numpy and filterpy"
venv="$ROOT/target/bench-venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
if ! "$venv/bin/python" -c 'import filterpy, numpy' 2>/dev/null; then
  "$venv/bin/pip" install --quiet --disable-pip-version-check numpy filterpy
fi

load_native="$(cut -d' ' -f1-3 /proc/loadavg)"
log "Native: cargo bench --bench pdr (writes target/bench-data/pdr_*)"
cargo bench --bench pdr --profile bench-import 2>&1 | tee "$results/criterion-pdr.log"

load_peer="$(cut -d' ' -f1-3 /proc/loadavg)"
log "Peers: bench/pdr_peer.py (filterpy ExtendedKalmanFilter, numpy loop)"
"$venv/bin/python" bench/pdr_peer.py "$data" > "$results/pdr_peer.json"

log "WebAssembly: release module into target/bench-wasm/pkg, bench/wasm/pdr.html in headless Chromium"
cargo build --release --lib --target wasm32-unknown-unknown
rm -rf "$ROOT/target/bench-wasm/pkg"
wasm-bindgen --target web --no-typescript --out-dir "$ROOT/target/bench-wasm/pkg" \
  "$ROOT/target/wasm32-unknown-unknown/release/compass_pdr.wasm"
load_wasm="$(cut -d' ' -f1-3 /proc/loadavg)"
TMPDIR="$run_tmp" XDG_CONFIG_HOME="$run_tmp/config" XDG_CACHE_HOME="$run_tmp/cache" \
  node bench/wasm-bench.mjs --runs 5 --page pdr.html > "$results/wasm-pdr.json"

BENCH_LOAD_NATIVE="$load_native" BENCH_LOAD_PEER="$load_peer" BENCH_LOAD_WASM="$load_wasm" \
BENCH_LOAD_END="$(cut -d' ' -f1-3 /proc/loadavg)" \
python3 - "$ROOT" <<'PY'
import json, os, sys

root = sys.argv[1]
env = os.environ


def load(*parts):
    with open(os.path.join(root, "target", *parts)) as file:
        return json.load(file)


def verdict(ok):
    return "met" if ok else "**NOT met**"


def max_diff(a, b):
    return max(abs(x - y) for x, y in zip(a, b))


settings = load("bench-data", "pdr_settings.json")
native = load("bench-data", "pdr_native.json")
peer = load("bench-results", "pdr_peer.json")
wasm = load("bench-results", "wasm-pdr.json")
n_steps = settings["n_steps"]
ekf_est = load("criterion", "pdr", f"ekf_{n_steps}", "new", "estimates.json")["median"]
pipe_est = load("criterion", "pdr", "pipeline_hour_100hz", "new", "estimates.json")["median"]

native_rate = n_steps / (ekf_est["point_estimate"] / 1e9)
native_ci = (n_steps / (ekf_est["confidence_interval"]["upper_bound"] / 1e9),
             n_steps / (ekf_est["confidence_interval"]["lower_bound"] / 1e9))
wasm_rate = wasm["ekf"]["steps_per_s"]
filterpy = peer["filterpy_ekf"]
numpy_loop = peer["numpy_loop"]
final_native = native["checkpoints"][str(n_steps)]["x"]
wasm_diff = max_diff(wasm["ekf"]["x"], final_native)
profile = native["pipeline"]
stages = profile["stages_s"]
pipe_native_s = pipe_est["point_estimate"] / 1e9
pipe_ci = (pipe_est["confidence_interval"]["lower_bound"] / 1e9,
           pipe_est["confidence_interval"]["upper_bound"] / 1e9)
pipe_wasm_s = wasm["pipeline"]["median_ms"] / 1e3


def rate(value):
    return f"{value / 1e6:.2f} M" if value >= 1e6 else f"{value / 1e3:.1f} k"


print()
print(f"PDR EKF: {n_steps:,} steps (`target/bench-data/pdr_steps.f64`, seed {settings['seed']}), "
      f"update of l and a with the wrapped heading innovation then Eq. 13's prediction; "
      f"the peers run the first {peer['n_steps']:,} steps of the same inputs")
print()
print("| run | steps/s | µs per step | this / filterpy | max \\|x − ours native\\| after the same steps | load (1, 5, 15 min) at start |")
print("|---|---|---|---|---|---|")
print(f"| ours, native (criterion median, 95% CI {rate(native_ci[0])}-{rate(native_ci[1])}) | **{rate(native_rate)}** "
      f"| {1e6 / native_rate:.3f} | {native_rate / filterpy['steps_per_s']:.0f}x | 0 | {env['BENCH_LOAD_NATIVE']} |")
rates = native["ekf_rates"]
cpu_rate = rates["steps_per_cpu_s"]
if cpu_rate:
    print(f"| ours, native, per second of this thread's CPU time ({rates['runs']} runs outside criterion, median; "
          f"per second of wall time {rate(rates['steps_per_wall_s'])}) | {rate(cpu_rate)} | {1e6 / cpu_rate:.3f} "
          f"| {cpu_rate / filterpy['steps_per_s']:.0f}x | 0 | {env['BENCH_LOAD_NATIVE']} |")
print(f"| ours, wasm (Chromium {wasm['chromium']}, {wasm['runs']} runs; copy of the inputs {wasm['ekf']['copy_ms']:.1f} ms included) "
      f"| **{rate(wasm_rate)}** | {1e6 / wasm_rate:.3f} | {wasm_rate / filterpy['steps_per_s']:.0f}x | {wasm_diff:.1e} | {env['BENCH_LOAD_WASM']} |")
print(f"| filterpy {peer['filterpy_version']} ExtendedKalmanFilter ({peer['runs']} runs) | **{rate(filterpy['steps_per_s'])}** "
      f"| {filterpy['us_per_step']:.1f} | 1x | {filterpy['max_abs_diff_x']:.1e} | {env['BENCH_LOAD_PEER']} |")
print(f"| numpy {peer['numpy_version']} loop, 4×4 arrays ({peer['runs']} runs) | **{rate(numpy_loop['steps_per_s'])}** "
      f"| {numpy_loop['us_per_step']:.1f} | {numpy_loop['steps_per_s'] / filterpy['steps_per_s']:.1f}x "
      f"| {numpy_loop['max_abs_diff_x']:.1e} | {env['BENCH_LOAD_PEER']} |")
print()
print(f"PDR pipeline: `{profile['file']}`, a simulated hour at {settings['hour_rate_hz']:g} Hz with GNSS "
      f"({profile['bytes'] / 1e6:.1f} MB of canonical CSV, {profile['n_samples']:,} samples, {profile['n_fixes']:,} fixes), "
      f"`import` then `pipeline::dead_reckoning` with the default options: {profile['n_steps']:,} steps, "
      f"{profile['distance_m']:.0f} m, heading `{profile['heading_key']}`")
print()
print("| run | median s | target | | load (1, 5, 15 min) at start |")
print("|---|---|---|---|---|")
print(f"| ours, native (criterion, 95% CI {pipe_ci[0]:.2f}-{pipe_ci[1]:.2f}) | **{pipe_native_s:.2f}** | < 1 s "
      f"| {verdict(pipe_native_s < 1.0)} | {env['BENCH_LOAD_NATIVE']} |")
print(f"| ours, wasm ({wasm['pipeline']['runs']} runs, {wasm['pipeline']['n_steps']:,} steps, "
      f"{wasm['pipeline']['distance_m']:.0f} m) | **{pipe_wasm_s:.2f}** | < 3 s | {verdict(pipe_wasm_s < 3.0)} "
      f"| {env['BENCH_LOAD_WASM']} |")
print()
total = profile["import_and_run_s"]
print(f"Native stages (each timed alone, median of {profile['runs']}; import + the pipeline {total:.2f} s):")
print()
print("| stage | s | share |")
print("|---|---|---|")
for key, label in [
    ("import", "`io::import::import`"),
    ("calibrate", "`analysis::calibration::calibrate` (field-domain fits, the log's reference)"),
    ("compare", "`analysis::headings::compare` (Fourier, RLS and MLP heading models)"),
    ("steps", "`pdr::steps::detect_steps`"),
    ("ekf", "`pdr::fusion::fuse` (the EKF with GNSS gating)"),
    ("report_clone", "the `ImportReport` clone the calibration takes"),
    ("other", "the rest (the chosen model fitted again on GNSS, step headings, frame, step model, metrics)"),
]:
    print(f"| {label} | {stages[key]:.3f} | {stages[key] / total * 100:.0f}% |")
print()
print("Each stage is timed on its own, so the stages need not add up to the whole; \"the rest\" is the "
      "whole minus the other stages and is within the noise when it is near zero or negative.")
print()
cpu_note = (f" (per second of CPU time, which leaves out the time other processes held the core: "
            f"{rate(cpu_rate)}, {'at or above' if cpu_rate >= 10e6 else 'below'} 10 M)") if cpu_rate else ""
print(f"- native EKF at least 10 M steps/s: {rate(native_rate)} steps/s (criterion, wall time), "
      f"{verdict(native_rate >= 10e6)}{cpu_note}")
print(f"- native EKF against filterpy: {native_rate / filterpy['steps_per_s']:.0f}x, filterpy taking "
      f"{filterpy['us_per_step']:.1f} µs a step (the issue's \"about 300x\" restates the 10 M target against "
      f"filterpy at about 35 µs a step; it is not a target of its own)")
print(f"- pipeline under 1 s natively: {pipe_native_s:.2f} s, {verdict(pipe_native_s < 1.0)}")
print(f"- pipeline under 3 s in the browser: {pipe_wasm_s:.2f} s, {verdict(pipe_wasm_s < 3.0)}")
print(f"- load (1, 5, 15 min) at the end: {env['BENCH_LOAD_END']}")
PY
