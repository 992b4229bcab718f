#!/usr/bin/env python3
"""Time to result on every real recording, in the page and natively (issue 20).

The end-to-end test tests/e2e/real.test.mjs drops each recording of ../shared/data on
the page as a person does and keeps, per recording, the time from the drop to the
summary and the page's longest main-thread task (tests/e2e/out/real-timing-*.json).
This runs the CLI's `pdr` command (the page's analysis: calibration, heading models,
dead reckoning) on the same files, best of `--runs` runs, and prints the table that
docs/BENCHMARKS.md keeps, with the page's time over the CLI's.

    python3 bench/real_logs.py target/release/compass-pdr tests/e2e/out [--runs 3]
"""
import argparse
import glob
import json
import os
import subprocess
import time


def cli_seconds(cli, files, runs):
    best = None
    for _ in range(runs):
        started = time.perf_counter()
        subprocess.run([cli, "pdr", *files], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
        elapsed = time.perf_counter() - started
        best = elapsed if best is None else min(best, elapsed)
    return best


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("cli")
    parser.add_argument("timings")
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    paths = sorted(glob.glob(os.path.join(args.timings, "real-timing-*.json")))
    if not paths:
        raise SystemExit(f"no real-timing-*.json in {args.timings}: run tests/e2e/real.test.mjs first (./test does)")
    print("| recording | size | CLI `pdr` (best of %d) | page, drop to summary | page / CLI | page, drop to every figure | longest main-thread task |" % args.runs)
    print("|---|---:|---:|---:|---:|---:|---:|")
    worst = 0.0
    for path in paths:
        timing = json.load(open(path))
        files = timing["files"]
        size_mb = sum(os.path.getsize(file) for file in files) / 1e6
        cli_s = cli_seconds(args.cli, files, args.runs)
        page_s = timing["dropToSummaryMs"] / 1e3
        ratio = page_s / cli_s
        worst = max(worst, ratio)
        ready_s = timing["dropToReadyMs"] / 1e3
        print(f"| {timing['name']} | {size_mb:.1f} MB | {cli_s:.3f} s | {page_s:.3f} s | {ratio:.2f} | {ready_s:.3f} s | {timing['longestTaskMs']:.0f} ms |")
    print()
    print(f"Largest page / CLI ratio: {worst:.2f}.")


if __name__ == "__main__":
    main()
