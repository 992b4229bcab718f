"""The file path a user takes, timed in one run: `compass-pdr inspect FILE --json` (a new
process reading the file from disk, as a user runs it) beside polars.read_csv and
pyarrow.csv.read_csv on the same file (in-process, the file read from disk each time).
Prints JSON: per tool the median and best wall time over `--runs`, the CPU time of the
median run (user + system, all threads), and MB/s on the median.

    python bench/file_path_peer.py CLI FILE [--runs 7]
"""

import json
import os
import resource
import statistics
import subprocess
import sys
import time


def timed(run, n_runs):
    walls, cpus = [], []
    for _ in range(n_runs):
        before_self = resource.getrusage(resource.RUSAGE_SELF)
        before_children = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.perf_counter()
        run()
        walls.append(time.perf_counter() - started)
        after_self = resource.getrusage(resource.RUSAGE_SELF)
        after_children = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(
            (after_self.ru_utime - before_self.ru_utime)
            + (after_self.ru_stime - before_self.ru_stime)
            + (after_children.ru_utime - before_children.ru_utime)
            + (after_children.ru_stime - before_children.ru_stime)
        )
    median_idx = sorted(range(n_runs), key=lambda idx: walls[idx])[n_runs // 2]
    return {
        "median_s": statistics.median(walls),
        "best_s": min(walls),
        "cpu_s_of_median_run": cpus[median_idx],
        "runs": n_runs,
    }


def main():
    cli, path = sys.argv[1], sys.argv[2]
    n_runs = int(sys.argv[sys.argv.index("--runs") + 1]) if "--runs" in sys.argv else 7
    import polars
    import pyarrow
    import pyarrow.csv

    size_mb = os.path.getsize(path) / 1e6
    tools = {
        "compass-pdr inspect": lambda: subprocess.run(
            [cli, "inspect", path, "--json"], check=True, stdout=subprocess.DEVNULL
        ),
        f"polars {polars.__version__} read_csv": lambda: polars.read_csv(path),
        f"pyarrow {pyarrow.__version__} csv.read_csv": lambda: pyarrow.csv.read_csv(path),
    }
    results = {"file": os.path.basename(path), "size_mb": size_mb, "cores": os.cpu_count(), "tools": {}}
    for name, run in tools.items():
        run()  # warm the page cache and the imports
        result = timed(run, n_runs)
        result["mb_per_s"] = size_mb / result["median_s"]
        results["tools"][name] = result
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
