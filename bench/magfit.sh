#!/usr/bin/env bash
# Autopilot compasses beside MAGFit: for every ArduPilot DataFlash log in
# ../shared/data, `compass-pdr calibrate LOG --param-out` beside ArduPilot WebTools' MAGFit
# run headless (../shared/peers/magfit/run_magfit.js: its default selection as its "Save
# Parameters" writes it, and its lowest-error valid fit per compass by magfit_best.py), all
# scored in one run of ../shared/peers/magfit/score.py (vector RMS against the WMM field seen
# through ATT + AHRS_TRIM, heading RMS against ATT yaw + declination, |B| spread) on the
# whole log and on the second half that compass-pdr holds back (from the median time of the
# compass samples paired with an attitude). Prints the docs/ACCURACY.md section; raw results
# in target/bench-results/magfit/. Idempotent. Not part of ./test.
#
#   bash bench/magfit.sh
set -euo pipefail
source "$(dirname "$0")/../scripts/setup.sh"
cd "$ROOT"
shared="$(cd "$ROOT/.." && pwd)/shared"
data_dir="$shared/data"
peer="$shared/peers/magfit"
results="$ROOT/target/bench-results/magfit"
port=8765
if [ ! -d "$data_dir" ]; then
  log "skipped: $data_dir not found (the real recordings live beside the project)"
  exit 0
fi
if [ ! -f "$peer/run_magfit.js" ] || [ ! -f "$peer/score.py" ]; then
  log "skipped: $peer not found (MAGFit, headless, and its scorer live beside the project)"
  exit 0
fi
mkdir -p "$results"

log "Python: venv at target/bench-venv with pymavlink, numpy and pygeomag (score.py)"
venv="$ROOT/target/bench-venv"
if [ ! -x "$venv/bin/python" ]; then
  python3 -m venv "$venv"
fi
"$venv/bin/pip" install --quiet --disable-pip-version-check pymavlink numpy pygeomag

log "MAGFit's browser: playwright-core (tests/e2e) and Chromium"
ensure_chromium
ensure_e2e_packages
export PLAYWRIGHT_CORE="$ROOT/tests/e2e/node_modules/playwright-core"
export CHROMIUM="${CHROMIUM:-$(command -v chromium)}"

log "compass-pdr: cargo build --release --bin compass-pdr"
cargo build --release --bin compass-pdr --quiet
cpdr="$ROOT/target/release/compass-pdr"

# The PIDs listening on MAGFit's port.
port_pids() {
  ss -ltnpH "sport = :$port" 2>/dev/null | grep -o 'pid=[0-9]*' | cut -d= -f2 | sort -u
}

# MAGFit's server (python3 -m http.server $port, started by run_magfit.js) must not outlive
# a run; anything else on the port is not ours, and the run cannot start.
free_port() {
  local pid
  for pid in $(port_pids); do
    if tr '\0' ' ' < "/proc/$pid/cmdline" 2>/dev/null | grep -q "http.server $port .*$peer/webtools"; then
      log "stopping MAGFit's leftover http.server (PID $pid) on port $port"
      kill "$pid" 2>/dev/null || true
      sleep 0.5
    else
      log "port $port is taken by PID $pid, which is not MAGFit's server: stop it and run again"
      exit 1
    fi
  done
  if [ -n "$(port_pids)" ]; then
    log "port $port is still taken"
    exit 1
  fi
}

# run_magfit.js LOG OUT.json: MAGFit prints "done ..." once it has saved its results, but its
# http.server child keeps node alive, so it runs under timeout and is stopped (with its
# process group: timeout forwards the signal to it) as soon as it is done.
run_magfit() {
  local log_file="$1" out="$2" pid rc=0
  shift 2
  free_port
  timeout 120 node "$peer/run_magfit.js" "$log_file" "$out" "$@" \
    > "${out%.json}.stdout" 2> "${out%.json}.stderr" &
  pid=$!
  while kill -0 "$pid" 2>/dev/null && ! grep -q '^done ' "${out%.json}.stdout"; do
    sleep 0.5
  done
  kill -TERM "$pid" 2>/dev/null || true
  wait "$pid" || rc=$?
  echo "$rc" > "${out%.json}.rc"
  free_port
}

commit="$(git -C "$ROOT" log -1 --oneline)"
src_status="$(git -C "$ROOT" status --short src)"
names=()
for log_file in "$data_dir"/ardupilot-copter-log171/log171.bin "$data_dir"/ardupilot-text-log/nan.log; do
  [ -f "$log_file" ] || { log "not found: $log_file"; continue; }
  name="$(basename "${log_file%.*}")"
  base="$results/$name"
  names+=("$name")
  rm -f "$base".*
  printf '{"log": "%s", "path": "%s"}\n' "$(basename "$(dirname "$log_file")")/$(basename "$log_file")" "$log_file" > "$base.meta.json"

  log "$name: compass-pdr calibrate --param-out"
  rc=0
  "$cpdr" calibrate "$log_file" --param-out "$base.compass-pdr.param" > "$base.compass-pdr.txt" 2>&1 || rc=$?
  echo "$rc" > "$base.compass-pdr.rc"
  "$cpdr" calibrate "$log_file" --json > "$base.compass-pdr.json"

  log "$name: MAGFit (run_magfit.js, then magfit_best.py)"
  run_magfit "$log_file" "$base.magfit.json" --adapter --source "ATTITUDEEKF 2 IMU 1"
  if [ ! -f "$base.magfit.json" ]; then
    # --source clicks the attitude source the page offers; a log the page cannot read
    # offers none, so the run fails before it saves what the page said. Once more without.
    log "$name: MAGFit saved nothing with --source; once more without it, for what the page says"
    mv "$base.magfit.stderr" "$base.magfit-with-source.stderr"
    run_magfit "$log_file" "$base.magfit.json" --adapter
  fi
  sets=()
  if [ -f "$base.magfit.MAGFit.param" ]; then
    sets+=("MAGFit default=$base.magfit.MAGFit.param")
    if "$venv/bin/python" "$peer/magfit_best.py" "$base.magfit.json" "$base.magfit-best.json" \
        > "$base.magfit-best.choice.json" 2> "$base.magfit-best.stderr"; then
      sets+=("MAGFit best=$base.magfit-best.json")
    fi
  fi
  if [ -f "$base.compass-pdr.param" ]; then
    sets+=("compass-pdr=$base.compass-pdr.param")
  fi

  log "$name: score.py on the whole log and on the held-back second half"
  "$venv/bin/python" bench/magfit_report.py split "$peer" "$log_file" "$base.split.json"
  "$venv/bin/python" "$peer/score.py" "$log_file" "${sets[@]}" --json "$base.score-whole.json" \
    > "$base.score-whole.txt" 2>&1 || log "$name: score.py failed on the whole log (see $base.score-whole.txt)"
  # The split is per compass; one scorer run per compass, each on its own second half.
  for i in $("$venv/bin/python" -c 'import json, sys; print(" ".join(json.load(open(sys.argv[1]))))' "$base.split.json"); do
    t0="$("$venv/bin/python" -c 'import json, sys; print(repr(json.load(open(sys.argv[1]))[sys.argv[2]]["split_s"]))' "$base.split.json" "$i")"
    "$venv/bin/python" "$peer/score.py" "$log_file" "${sets[@]}" --window "$t0,1e12" --json "$base.score-half-$i.json" \
      > "$base.score-half-$i.txt" 2>&1 || log "$name: score.py failed on the second half (see $base.score-half-$i.txt)"
  done
done

{
  echo "Run on $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores ($(lscpu | sed -n 's/^Model name: *//p' | head -1)), at \`$commit\`; \`git status --short src\`: $([ -n "$src_status" ] && echo "uncommitted changes in src/ ($(echo "$src_status" | wc -l) entries)" || echo "clean")."
  echo
  "$venv/bin/python" bench/magfit_report.py report "$results" "${names[@]}"
} | tee "$results/magfit.md"
