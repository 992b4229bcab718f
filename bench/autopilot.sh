#!/usr/bin/env bash
# Autopilot logs: compass-pdr's import of the DataFlash (.bin, .log) and ULog files in
# ../shared/data, and of log171 repeated ten times (30 MB), beside pymavlink (every
# message, as mavlogdump.py reads a log; and only the messages compass-pdr uses) and
# pyulog (every topic; and only the topics used) on the same files in the same run,
# with the peak memory of each on the 30 MB log. Prints the docs/BENCHMARKS.md section;
# raw results in target/bench-results/autopilot*. Idempotent. Not part of ./test.
#
#   bench/autopilot.sh
set -euo pipefail
source "$(dirname "$0")/../scripts/setup.sh"
cd "$ROOT"
results="$ROOT/target/bench-results"
data_dir="$(cd "$ROOT/.." && pwd)/shared/data"
mkdir -p "$results"
if [ ! -d "$data_dir" ]; then
  log "skipped: $data_dir not found (the real recordings live beside the project)"
  exit 0
fi

log "Python peers: venv at target/bench-venv with pymavlink and pyulog"
venv="$ROOT/target/bench-venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check pymavlink pyulog

load_native="$(cut -d' ' -f1-3 /proc/loadavg)"
log "Native: cargo bench --bench autopilot (writes target/bench-data/log171x10.bin)"
cargo bench --bench autopilot --profile bench-import | tee "$results/autopilot.jsonl"
cargo build --profile bench-import --bin compass-pdr --quiet

load_peer="$(cut -d' ' -f1-3 /proc/loadavg)"
log "Peers: bench/autopilot_peer.py"
big="$ROOT/target/bench-data/log171x10.bin"
"$venv/bin/python" bench/autopilot_peer.py --runs 3 \
  "$data_dir/ardupilot-copter-log171/log171.bin" "$data_dir/ardupilot-text-log/nan.log" \
  "$data_dir/px4-ulog/sample.ulg" "$data_dir/px4-ulog/sample_log_small.ulg" \
  > "$results/autopilot_peer.jsonl"
"$venv/bin/python" bench/autopilot_peer.py --runs 1 "$big" >> "$results/autopilot_peer.jsonl"

log "Peak memory on the 30 MB log: /usr/bin/time -v"
/usr/bin/time -v target/bench-import/compass-pdr inspect "$big" --json > /dev/null 2> "$results/autopilot-time-ours.txt"
/usr/bin/time -v "$venv/bin/python" bench/autopilot_peer.py --runs 1 --only-all "$big" > /dev/null 2> "$results/autopilot-time-peer.txt"

BENCH_LOAD_NATIVE="$load_native" BENCH_LOAD_PEER="$load_peer" python3 - "$results" <<'PY'
import json, os, re, sys
results = sys.argv[1]
ours = [json.loads(line) for line in open(os.path.join(results, "autopilot.jsonl")) if line.startswith("{")]
peers = [json.loads(line) for line in open(os.path.join(results, "autopilot_peer.jsonl"))]
def rss_mb(name):
    text = open(os.path.join(results, name)).read()
    match = re.search(r"Maximum resident set size \(kbytes\): (\d+)", text)
    return int(match.group(1)) / 1024 if match else float("nan")
names = {"log171.bin × 10": "log171x10.bin"}
print("## Autopilot logs")
print()
print("Written by `bench/autopilot.sh`: `cargo bench --bench autopilot --profile bench-import` "
      "(`io::import::import`, detection included, median of 15 reads after a warm-up) and "
      "`bench/autopilot_peer.py` (median of 3 runs; 1 on the 30 MB log) on the same files, one after the other. "
      f"Load average before ours: {os.environ['BENCH_LOAD_NATIVE']}; before the peers: {os.environ['BENCH_LOAD_PEER']}.")
print()
print("| file | size | compass-pdr | peer | peer time | compass-pdr faster |")
print("|---|---:|---:|---|---:|---:|")
for entry in ours:
    base = names.get(entry["file"], os.path.basename(entry["file"]))
    for peer in [p for p in peers if p["file"] == base]:
        print(f"| {entry['file']} | {entry['bytes'] / 1e6:.2f} MB | {entry['median_s'] * 1e3:.1f} ms "
              f"({entry['bytes'] / entry['median_s'] / 1e6:.0f} MB/s) | {peer['peer']} | "
              f"{peer['median_s'] * 1e3:.0f} ms | {peer['median_s'] / entry['median_s']:.0f}× |")
print()
print(f"Peak memory on the 30 MB log: `compass-pdr inspect --json` {rss_mb('autopilot-time-ours.txt'):.0f} MB "
      f"(the whole file is read in chunks; the samples are kept), pymavlink reading every message "
      f"{rss_mb('autopilot-time-peer.txt'):.0f} MB.")
PY
