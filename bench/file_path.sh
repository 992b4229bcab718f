#!/usr/bin/env bash
# The CSV file path a user takes (issue 20): `compass-pdr inspect` on a ~100 MB canonical
# CSV, a new process reading the file from disk, beside polars and pyarrow reading the
# same file in the same run (bench/file_path_peer.py). Writes
# target/bench-results/file-path.json and prints its table as markdown (bench/run
# appends it to docs/BENCHMARKS.md).
# Idempotent: the venv, the input and the build are reused.
#
#   bench/file_path.sh
set -euo pipefail
source "$(dirname "$0")/../scripts/setup.sh"
cd "$ROOT"
results="$ROOT/target/bench-results"
data="$ROOT/target/bench-data"
mkdir -p "$results" "$data"
venv="$ROOT/target/bench-venv"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --disable-pip-version-check polars pyarrow
cargo build --release --quiet --bin compass-pdr
input="$data/walk-100mb.csv"
if [ ! -f "$input" ]; then
  log "Writing $input (compass-pdr simulate, 5 h at 100 Hz: about 100 MB)"
  target/release/compass-pdr simulate --scenario steady --seed 9 --duration-s 17700 --out "$input"
fi
log "compass-pdr inspect, polars.read_csv and pyarrow.csv.read_csv on $(basename "$input") ($(stat -c %s "$input") bytes)"
load="$(cut -d' ' -f1-3 /proc/loadavg)"
"$venv/bin/python" bench/file_path_peer.py target/release/compass-pdr "$input" --runs 7 > "$results/file-path.json"
"$venv/bin/python" - "$results/file-path.json" "$load" <<'PY'
import json, sys
results = json.load(open(sys.argv[1]))
print(f"File: `target/bench-data/{results['file']}` ({results['size_mb'] * 1e6:,.0f} bytes), {results['cores']} cores, load average before the run {sys.argv[2]}.")
print()
print("| tool | how | median wall | best | CPU of the median run | MB/s (median) |")
print("|---|---|---:|---:|---:|---:|")
ways = {"new_process": "new process each run", "in_process": "one process, after a warm-up"}
for name, tool in results["tools"].items():
    for way, label in ways.items():
        if way in tool:
            t = tool[way]
            print(f"| {name} | {label} | {t['median_s']:.3f} s | {t['best_s']:.3f} s | {t['cpu_s_of_median_run']:.3f} s | {t['mb_per_s']:.0f} |")
print()
ours = next(tool for name, tool in results["tools"].items() if name.startswith("compass-pdr"))["new_process"]["median_s"]
for name, tool in results["tools"].items():
    if name.startswith("compass-pdr"):
        continue
    ratios = ", ".join(f"{tool[way]['median_s'] / ours:.2f}× its {ways[way]} median" for way in ways if way in tool)
    print(f"- compass-pdr against {name}: {ratios}.")
PY
