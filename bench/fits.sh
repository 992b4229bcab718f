#!/usr/bin/env bash
# The fits on real logs in one go: the ellipse (tilt-aware level-plane) and
# 3D (fit::ellipsoid) fits on 10⁴ samples of each real recording in ../shared/data, of
# the simulator's demo walk and of the independent generator's circle walk, natively
# (criterion, benches/fits.rs, which also writes the samples and the outcomes), and
# numpy's Li-Griffiths fit and an ArduPilot-style scipy LM on the same samples
# (bench/fits_peer.py). Prints the docs/BENCHMARKS.md section; raw results in
# target/bench-results/fits*. Idempotent (the venv and the builds are reused). Not part
# of ./test; bench/run calls it.
#
#   bench/fits.sh
set -euo pipefail
source "$(dirname "$0")/../scripts/setup.sh"
cd "$ROOT"
results="$ROOT/target/bench-results"
data="$ROOT/target/bench-data"
mkdir -p "$results"

log "Python peers: venv at target/bench-venv with numpy and scipy"
venv="$ROOT/target/bench-venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check numpy scipy

load_native="$(cut -d' ' -f1-3 /proc/loadavg)"
log "Native: cargo bench --bench fits (writes target/bench-data/fits_*.f64)"
rm -f "$data"/fits_*.f64
cargo bench --bench fits --profile bench-import 2>&1 | tee "$results/criterion-fits.log"

load_peer="$(cut -d' ' -f1-3 /proc/loadavg)"
log "Peers: bench/fits_peer.py (numpy Li-Griffiths, scipy LM as ArduPilot's calibrator)"
"$venv/bin/python" bench/fits_peer.py "$data" > "$results/fits_peer.json"

BENCH_LOAD_NATIVE="$load_native" BENCH_LOAD_PEER="$load_peer" python3 - "$ROOT" <<'PY'
import json, os, sys

root = sys.argv[1]
env = os.environ
fits = json.load(open(os.path.join(root, "target", "bench-results", "fits.json")))
peer = json.load(open(os.path.join(root, "target", "bench-results", "fits_peer.json")))


def criterion_ms(fit, case):
    path = os.path.join(root, "target", "criterion", "fits", fit, case, "new", "estimates.json")
    if not os.path.exists(path):
        return None
    median = json.load(open(path))["median"]
    return (median["point_estimate"] / 1e6, median["confidence_interval"]["lower_bound"] / 1e6,
            median["confidence_interval"]["upper_bound"] / 1e6)


def ms(value):
    return "—" if value is None else f"{value[0]:.1f}"


def outcome(entry):
    if "refused" in entry:
        return "refused"
    h = entry["hard_iron_ut"]
    return f"{entry['model']}, h ({h[0]:.1f}, {h[1]:.1f}, {h[2]:.1f}), residual {entry['residual_rms_ut']:.2f}"


rows, worst = [], {"ellipse": 0.0, "ellipsoid": 0.0}
for case, entry in fits["cases"].items():
    ellipse, ellipsoid = criterion_ms("ellipse", case), criterion_ms("ellipsoid", case)
    for fit, value in (("ellipse", ellipse), ("ellipsoid", ellipsoid)):
        if value is not None:
            worst[fit] = max(worst[fit], value[0])
    p = peer["cases"].get(case, {})
    numpy_ms = p.get("numpy_median_s")
    scipy_ms = p.get("scipy_lm_median_s")
    scipy_h = p.get("scipy_lm_hard_iron")
    rows.append(
        f"| {case} | {entry['n_source']:,} | {ms(ellipse)} | {ms(ellipsoid)} | "
        f"{'—' if numpy_ms is None else f'{numpy_ms * 1e3:.1f}'} | "
        f"{'—' if scipy_ms is None else f'{scipy_ms * 1e3:.1f}'} | "
        f"{outcome(entry['ellipsoid'])} | "
        f"{'—' if scipy_h is None else '(' + ', '.join(f'{v:.1f}' for v in scipy_h) + ')'} |"
    )

print(f"""Fits on real logs: {fits['n_samples']:,} samples of each recording (evenly thinned or repeated), made as `calibrate` makes them (import, tilt, the WMM's priors); median ms

| case | samples in the log | ellipse (ours) | 3D fit (ours) | numpy Li-Griffiths | scipy LM (ArduPilot-style) | our 3D fit's outcome (h in the log's unit) | scipy LM's h |
|---|---|---|---|---|---|---|---|
""" + "\n".join(rows) + f"""

Load (1, 5, 15 min) at the start: ours {env['BENCH_LOAD_NATIVE']}, the peers {env['BENCH_LOAD_PEER']}; numpy {peer['numpy']}, scipy {peer['scipy']}.
The peers fit the magnitude alone (no accelerometer, no prior, no robust weights): the fastest well-known 3D fits on the same samples, not the same estimator.

- ellipse under 50 ms on every log: {'met' if worst['ellipse'] < 50 else 'not met'} (slowest {worst['ellipse']:.1f} ms)
- 3D fit under 50 ms on every log: {'met' if worst['ellipsoid'] < 50 else 'not met'} (slowest {worst['ellipsoid']:.1f} ms)""")
PY
