#!/usr/bin/env python3
"""The peers of compass-pdr's importer on the benchmark inputs, for docs/BENCHMARKS.md.

Reads the files `cargo bench --bench import` generates under target/bench-data/:
pandas.read_csv on walk.csv (the canonical CSV) and pynmea2.parse on every line of
track.nmea (the NMEA log), the way a user would write it: a loop over the lines,
catching pynmea2's parse errors. Each is timed several times, wall clock (reading the
file from the page cache included) and CPU time of all threads; the medians are
reported.

Prints one JSON object on stdout. Usage: peers.py [DATA_DIR] [--csv-runs N] [--nmea-runs N]
"""

import argparse
import json
import os
import statistics
import sys
import time

import pandas
import pynmea2


def time_runs(n_runs, work):
    """Wall-clock and CPU seconds (all threads of this process) of each run."""
    seconds = []
    cpu_seconds = []
    result = None
    for _ in range(n_runs):
        start = time.perf_counter()
        cpu_start = time.process_time()
        result = work()
        cpu_seconds.append(time.process_time() - cpu_start)
        seconds.append(time.perf_counter() - start)
    return (seconds, cpu_seconds), result


def read_csv(path):
    frame = pandas.read_csv(path)
    return {"rows": int(frame.shape[0]), "columns": int(frame.shape[1])}


def parse_nmea(path):
    n_parsed = 0
    n_errors = 0
    # newline="" keeps the CR of CRLF; pynmea2 strips surrounding whitespace itself.
    with open(path, "r", encoding="ascii", errors="replace", newline="") as lines:
        for line in lines:
            try:
                pynmea2.parse(line)
                n_parsed += 1
            except pynmea2.ParseError:
                n_errors += 1
    return {"sentences": n_parsed, "parse_errors": n_errors}


def summary(path, timings, result):
    seconds, cpu_seconds = timings
    size = os.path.getsize(path)
    median_s = statistics.median(seconds)
    return {
        "file": os.path.basename(path),
        "bytes": size,
        "runs": len(seconds),
        "seconds": [round(s, 4) for s in seconds],
        "cpu_seconds": [round(s, 4) for s in cpu_seconds],
        "median_s": median_s,
        "median_cpu_s": statistics.median(cpu_seconds),
        "mb_per_s": size / 1e6 / median_s,
        "result": result,
    }


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "data_dir", nargs="?", default=os.path.join(here, "..", "target", "bench-data")
    )
    parser.add_argument("--csv-runs", type=int, default=5)
    # One pynmea2 pass over the 100 MB log takes about 10 s here, so five passes fit in
    # bench/run's time budget; lower this on a slower machine.
    parser.add_argument("--nmea-runs", type=int, default=5)
    args = parser.parse_args()

    csv_path = os.path.join(args.data_dir, "walk.csv")
    nmea_path = os.path.join(args.data_dir, "track.nmea")
    for path in (csv_path, nmea_path):
        if not os.path.exists(path):
            sys.exit(f"{path} is missing: run bench/run (its cargo bench step writes it)")

    results = {
        "python": sys.version.split()[0],
        "pandas": pandas.__version__,
        "pynmea2": getattr(pynmea2, "__version__", "unknown"),
    }
    timings, result = time_runs(args.csv_runs, lambda: read_csv(csv_path))
    results["pandas_read_csv"] = summary(csv_path, timings, result)
    print(f"pandas.read_csv: median {results['pandas_read_csv']['median_s']:.3f} s", file=sys.stderr)
    timings, result = time_runs(args.nmea_runs, lambda: parse_nmea(nmea_path))
    results["pynmea2_parse"] = summary(nmea_path, timings, result)
    print(f"pynmea2.parse: median {results['pynmea2_parse']['median_s']:.3f} s", file=sys.stderr)
    json.dump(results, sys.stdout, indent=2)
    print()


if __name__ == "__main__":
    main()
