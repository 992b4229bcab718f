#!/usr/bin/env bash
# The attitude filter against motion capture: compass-pdr's heading (`heading
# --attitude-out`) on each TYREX trial in ../shared/data/tyrex-attitude and
# tyrex-attitude-more (nine), scored with the phone's rotation vector, imufusion's Fusion
# AHRS, the `ahrs` package's Madgwick and VQF on the same samples by
# bench/attitude_peers.py; the filter's own speed from
# `cargo bench --bench attitude`. Prints the markdown section (bench/accuracy.sh appends
# it to docs/ACCURACY.md); the figures go to target/bench-results/attitude*.json.
# About a minute after the build.
#
#   bench/attitude.sh
set -euo pipefail
source "$(dirname "$0")/../scripts/setup.sh"
cd "$ROOT"
ensure_rust
data="$ROOT/../shared/data/tyrex-attitude"
more="$ROOT/../shared/data/tyrex-attitude-more"
if [ ! -d "$data" ]; then
  printf '\n## Attitude against motion capture\n\nSkipped: %s not found.\n' "$data"
  exit 0
fi
venv="$ROOT/target/bench-venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv" >&2
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check numpy scipy imufusion ahrs vqf >&2
cargo build --profile bench-import --bin compass-pdr --quiet >&2
results="$ROOT/target/bench-results"
ours="$results/attitude"
mkdir -p "$ours"
for trial in "$data"/*/ "$more"/*/; do
  [ -d "$trial" ] || continue
  name=$(basename "$trial")
  target/bench-import/compass-pdr heading "$trial"*.txt "$trial"record.properties \
    --attitude-out "$ours/$name.csv" > "$ours/$name.txt" 2>&1
done
cargo bench --bench attitude --profile bench-import >&2
printf '\n## Attitude against motion capture (TYREX, issue 18)\n\n'
printf 'Nine trials (five in tyrex-attitude, four in tyrex-attitude-more) of the attitude benchmark of Michel et al. (Nexus 5; Qualisys truth at 60 Hz). `compass-pdr heading TRIAL/*.txt --attitude-out TRIAL.csv`\n'
printf '(the filter of `src/attitude` run forward and backward over the log, the yaws weighed by their σ: `attitude::smoother`; field corrected by the analysis'"'"'s calibration or the phone'"'"'s own estimate, whichever\n'
printf 'lets the gates pass more field) beside the phone'"'"'s rotation vector, imufusion 1.3.3 (Fusion AHRS, gain 0.5, acceleration and magnetic\n'
printf 'rejection 10°, recovery 5 s), ahrs 0.4.0 (Madgwick MARG, its default gain 0.041) and vqf 2.1.2 (VQF, Laidig and Seel 2023, its defaults, magnetic\ndisturbance rejection on; `vqf_offline` is its offline variant, which reads the whole log as ours does, the like-for-like peer; the others are causal), all fed the same gyroscope, accelerometer and\n'
printf 'OS-calibrated magnetometer samples; `gyro` is the gyroscope alone from the rotation vector'"'"'s first attitude (a reference, not a\n'
printf 'peer). Frames, alignment and exclusions: `bench/attitude_peers.py`'"'"'s header. Made by `bench/attitude.sh`.\n\n'
printf 'Caveats: the gates'"'"' tolerances (field magnitude 15 %%, dip 10°, direction 6° over 1.5 s) were chosen while looking at these five\n'
printf 'trials (tighter ones refused nearly every field sample of the pocket and swinging trials), so they are not an independent test\n'
printf '(the four of tyrex-attitude-more came later and no setting was chosen on them: they are);\n'
printf 'the peers run with their documented defaults, not tuned per trial (Michel et al. report a tuned Madgwick at 4.3-13.1° with\n'
printf 'disturbances over 42 trials). The filter'"'"'s prior on the gyroscope'"'"'s bias follows what the log says of it: these\n'
printf 'trials'"'"' gyroscopes are Android'"'"'s `TYPE_GYROSCOPE`, the bias removed by the OS, so it starts at 0.002 rad/s 1σ\n'
printf '(`attitude::REMOVED_BIAS_SIGMA_RADPS`), where a raw gyroscope starts at 0.01 rad/s. That choice matters here: with the raw\n'
printf 'prior the filter gave 16.6 / 7.6 / 10.4 / 5.8 / 2.1° on the five trials; with 0.001 rad/s 3.8 / 4.3 / 9.3 / 5.5 / 2.2°, with 0.004\n'
printf 'rad/s 9.2 / 5.8 / 9.3 / 5.9 / 2.0° (runs of 2026-11-27): the tighter the prior, the less a disturbed field that passes the gates\n'
printf 'can teach the filter a false bias. The 0.002 was chosen with these trials in view (as a round figure for the residual of an\n'
printf 'OS'"'"'s running bias estimate, about 0.1°/s, not fitted to them), so it is not an independent test either.\n\n'
"$venv/bin/python" bench/attitude_peers.py "$data" "$more" --ours "$ours" --json "$results/attitude.json" --truth-out "$results/tyrex-truth" 2>/dev/null
"$venv/bin/python" - "$results/attitude.json" <<'PY'
import json, statistics, sys
trials = [t for t in json.load(open(sys.argv[1]))["trials"] if "methods" in t and "ours" in t["methods"]]
peers = ["rotation_vector", "fusion", "madgwick", "vqf", "vqf_offline"]
ratios = []
for t in trials:
    best = min(t["methods"][m]["rms_deg"] for m in peers)
    ratios.append((t["trial"].replace("Thibaud_Nexus5_", ""), t["methods"]["ours"]["rms_deg"] / best))
ours_median = statistics.median(t["methods"]["ours"]["rms_deg"] for t in trials)
peer_medians = {m: statistics.median(t["methods"][m]["rms_deg"] for t in trials) for m in peers}
best_peer = min(peer_medians, key=peer_medians.get)
within = sum(r <= 1.1 for _, r in ratios)
print(f"\nIssue 43's bar, over the {len(trials)} trials: ours against the best peer of each trial, "
      + ", ".join(f"{name} {r:.2f} ×" for name, r in ratios)
      + f"; {within} of {len(trials)} within 1.1 ×. Median over the trials: ours {ours_median:.1f}°, the best peer's "
      f"({best_peer}) {peer_medians[best_peer]:.1f}° ({ours_median / peer_medians[best_peer]:.2f} ×; the bar is 0.8 ×).")
PY
"$venv/bin/python" - "$results/attitude_ours.json" <<'PY'
import json, sys
ours = json.load(open(sys.argv[1]))
samples = sum(t["samples"] for t in ours.values())
seconds = sum(t["median_s"] for t in ours.values())
rate = samples / seconds
cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")), "this machine")
verdict = "met" if rate >= 1e7 else "not met"
print(f"\nOur filter alone (`cargo bench --bench attitude`, one run per trial, the median of 20): {samples} samples "
      f"(gyroscope + accelerometer + magnetometer) in {seconds:.3f} s, {rate / 1e6:.1f} M samples/s natively on one core of "
      f"{cpu} (the issue's target is 10 M/s: {verdict} here). The peers' times above are their Python loops, per gyroscope sample.")
PY
