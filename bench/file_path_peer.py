"""The file path a user takes, timed in one run: `compass-pdr inspect FILE --json` (a new
process reading the file from disk, as a user runs it) beside polars.read_csv and
pyarrow.csv.read_csv on the same file, the file in the page cache for all three.

The peers are timed two ways:
- `new_process`: each run a new Python process that imports the library first and then
  times one read (the interpreter's start and the import are left out of the time).
  Like the CLI, each read then writes its table into memory the process has never
  touched, and starts its threads;
- `in_process`: one process reading the file again and again after a first read, as
  the peers' own benchmarks do. From the second read on, the allocator hands back the
  memory of the table before (jemalloc keeps it), already mapped, so the kernel does
  not zero fresh pages for it. On this machine, a VM whose memory the host reclaims,
  that zeroing is what varies most (docs/BENCHMARKS.md).

Prints JSON: per tool and way the median and best wall time over `--runs`, the CPU time
of the median run (user + system, all threads), and MB/s on the median.

    python bench/file_path_peer.py CLI FILE [--runs 7]
"""

import json
import os
import resource
import statistics
import subprocess
import sys
import time


def summarised(walls, cpus):
    """The median and best wall time of the runs, and the CPU time of the median run."""
    median_idx = sorted(range(len(walls)), key=lambda idx: walls[idx])[len(walls) // 2]
    return {
        "median_s": statistics.median(walls),
        "best_s": min(walls),
        "cpu_s_of_median_run": cpus[median_idx],
        "runs": len(walls),
    }


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
    return summarised(walls, cpus)


NEW_PROCESS_READ = """
import resource, sys, time
import {module}
path = sys.argv[1]
before = resource.getrusage(resource.RUSAGE_SELF)
started = time.perf_counter()
{call}(path)
wall = time.perf_counter() - started
after = resource.getrusage(resource.RUSAGE_SELF)
print(wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime))
"""


def timed_new_process(module, call, path, n_runs):
    """One read in each of `n_runs` new Python processes, timed inside the process."""
    walls, cpus = [], []
    script = NEW_PROCESS_READ.format(module=module, call=call)
    for _ in range(n_runs):
        out = subprocess.run(
            [sys.executable, "-c", script, path], check=True, capture_output=True, text=True
        ).stdout.split()
        walls.append(float(out[0]))
        cpus.append(float(out[1]))
    return summarised(walls, cpus)


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
    new_process = {
        f"polars {polars.__version__} read_csv": ("polars", "polars.read_csv"),
        f"pyarrow {pyarrow.__version__} csv.read_csv": ("pyarrow.csv", "pyarrow.csv.read_csv"),
    }
    for name, run in tools.items():
        run()  # warm the page cache and the imports
        result = {}
        if name in new_process:
            module, call = new_process[name]
            result["new_process"] = timed_new_process(module, call, path, n_runs)
            result["in_process"] = timed(run, n_runs)
        else:
            # The CLI is a new process each run: its time is its whole life.
            result["new_process"] = timed(run, n_runs)
        for way in result.values():
            way["mb_per_s"] = size_mb / way["median_s"]
        results["tools"][name] = result
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
