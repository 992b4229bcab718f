#!/usr/bin/env python3
"""Time to result on every real recording, in the page and natively (issue 20).

The end-to-end test tests/e2e/real.test.mjs drops each recording of ../shared/data on
the page as a person does and keeps, per recording, the time from the drop to the
summary and the page's longest main-thread task (tests/e2e/out/real-timing-*.json), for
each of its first drops on fresh pages (`firstDrops`; one drop in files from before
2026-12-06). This runs the CLI's `pdr` command (the page's analysis: calibration,
heading models, dead reckoning) on the same files, best of `--runs` runs, and prints the
table that docs/BENCHMARKS.md keeps: the page's median first drop, its time over the
CLI's best, and the longest main-thread task of any of its drops.

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


def median(values):
    ordered = sorted(values)
    middle = len(ordered) // 2
    return ordered[middle] if len(ordered) % 2 else (ordered[middle - 1] + ordered[middle]) / 2


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("cli")
    parser.add_argument("timings")
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    paths = sorted(glob.glob(os.path.join(args.timings, "real-timing-*.json")))
    if not paths:
        raise SystemExit(f"no real-timing-*.json in {args.timings}: run tests/e2e/real.test.mjs first (./test does)")
    timings = [json.load(open(path)) for path in paths]
    n_drops = max(len(timing.get("firstDrops", [timing])) for timing in timings)
    print(
        f"| recording | size | CLI `pdr` (best of {args.runs}) | page, drop to summary (median of {n_drops} first drops) "
        "| page / CLI | the drops to summary | page, drop to every figure (median) | longest main-thread task |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    worst = 0.0
    for timing in timings:
        files = timing["files"]
        drops = timing.get("firstDrops", [timing])
        size_mb = sum(os.path.getsize(file) for file in files) / 1e6
        cli_s = cli_seconds(args.cli, files, args.runs)
        page_s = median([drop["dropToSummaryMs"] for drop in drops]) / 1e3
        ratio = page_s / cli_s
        worst = max(worst, ratio)
        ready_s = median([drop["dropToReadyMs"] for drop in drops]) / 1e3
        each = ", ".join(f"{drop['dropToSummaryMs']:.0f}" for drop in drops)
        longest_ms = max(drop["longestTaskMs"] for drop in drops)
        print(
            f"| {timing['name']} | {size_mb:.1f} MB | {cli_s:.3f} s | {page_s:.3f} s | {ratio:.2f} | {each} ms "
            f"| {ready_s:.3f} s | {longest_ms:.0f} ms |"
        )
    print()
    print(f"Largest page / CLI ratio: {worst:.2f}.")


if __name__ == "__main__":
    main()
