"""The ellipsoid-fit peer of benches/ellipsoid.rs: numpy's Li-Griffiths algebraic fit
(Li and Griffiths 2004, the algorithm of Magneto 1.2) on the same samples.

Reads target/bench-data/sphere_<n>.f64 (little-endian float64 x, y, z triples, written
by the Rust benchmark) and prints, as JSON, the median time of the fit for each size,
with the hard iron it found (so that both tools are seen to solve the same problem).
"""
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np


def li_griffiths(x, y, z):
    """Centre and quadric of the ellipsoid-specific least-squares fit (k = 4)."""
    d = np.array([x * x, y * y, z * z, 2 * y * z, 2 * x * z, 2 * x * y, 2 * x, 2 * y, 2 * z, np.ones_like(x)])
    s = d @ d.T
    s11, s12, s21, s22 = s[:6, :6], s[:6, 6:], s[6:, :6], s[6:, 6:]
    c = np.array([
        [-1, 1, 1, 0, 0, 0],
        [1, -1, 1, 0, 0, 0],
        [1, 1, -1, 0, 0, 0],
        [0, 0, 0, -4, 0, 0],
        [0, 0, 0, 0, -4, 0],
        [0, 0, 0, 0, 0, -4],
    ], dtype=float)
    e = np.linalg.inv(c) @ (s11 - s12 @ np.linalg.inv(s22) @ s21)
    values, vectors = np.linalg.eig(e)
    v1 = np.real(vectors[:, np.argmax(np.real(values))])
    if v1[0] < 0:
        v1 = -v1
    v2 = -np.linalg.inv(s22) @ s21 @ v1
    a, b, cc, f, g, h = v1
    p, q, r, dd = v2
    m = np.array([[a, h, g], [h, b, f], [g, f, cc]])
    centre = -np.linalg.inv(m) @ np.array([p, q, r])
    return centre, m, dd


def main():
    data_dir = Path(sys.argv[1] if len(sys.argv) > 1 else "target/bench-data")
    results = {}
    for path in sorted(data_dir.glob("sphere_*.f64"), key=lambda p: int(p.stem.split("_")[1])):
        samples = np.fromfile(path, dtype="<f8").reshape(-1, 3)
        x, y, z = samples[:, 0].copy(), samples[:, 1].copy(), samples[:, 2].copy()
        n = len(samples)
        runs = 21 if n <= 100_000 else 7
        times = []
        centre = None
        for _ in range(runs):
            start = time.perf_counter()
            centre, _, _ = li_griffiths(x, y, z)
            times.append(time.perf_counter() - start)
        results[str(n)] = {"median_s": statistics.median(times), "runs": runs, "hard_iron_ut": [float(v) for v in centre]}
    json.dump({"numpy": np.__version__, "fits": results}, sys.stdout, indent=2)
    print()


if __name__ == "__main__":
    main()
