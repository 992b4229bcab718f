"""The ellipsoid-fit peers of benches/ellipsoid.rs on the same samples: numpy's
Li-Griffiths algebraic fit (Li and Griffiths 2004, the algorithm of Magneto 1.2), and an
ArduPilot-style Levenberg-Marquardt fit with scipy.optimize.least_squares(method="lm").

ArduPilot's CompassCalibrator (libraries/AP_Compass/CompassCalibrator.cpp) fits, by
Levenberg-Marquardt on the residual `radius - |S (m + offset)|`, first a sphere (radius
and offset, S = I) and then an ellipsoid (offset, the diagonal and off-diagonal of a
symmetric S, with the radius kept); this peer does the same two steps with SciPy's
MINPACK LM, from ArduPilot's start (offset 0, radius 200 mGauss there; here the mean
distance to the mean sample), on every sample. ArduPilot itself fits on a buffer of
300 samples thinned by direction; fitting all of them is what a user of scipy does.

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
from scipy.optimize import least_squares


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


def ardupilot_lm(samples):
    """Offset (hard iron = -offset) by ArduPilot's two-step LM: sphere, then ellipsoid."""
    start_offset = -samples.mean(axis=0)
    start_radius = np.linalg.norm(samples + start_offset, axis=1).mean()

    def sphere_residuals(p):
        return p[0] - np.linalg.norm(samples + p[1:4], axis=1)

    sphere = least_squares(sphere_residuals, np.concatenate([[start_radius], start_offset]), method="lm")
    radius = sphere.x[0]

    def ellipsoid_residuals(p):
        offset, diag, offdiag = p[0:3], p[3:6], p[6:9]
        s = np.array([
            [diag[0], offdiag[0], offdiag[1]],
            [offdiag[0], diag[1], offdiag[2]],
            [offdiag[1], offdiag[2], diag[2]],
        ])
        return radius - np.linalg.norm((samples + offset) @ s.T, axis=1)

    start = np.concatenate([sphere.x[1:4], [1.0, 1.0, 1.0], [0.0, 0.0, 0.0]])
    ellipsoid = least_squares(ellipsoid_residuals, start, method="lm")
    return -ellipsoid.x[0:3], ellipsoid.nfev + sphere.nfev


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
        lm_runs = 7 if n <= 100_000 else 3
        lm_times = []
        lm_centre, evaluations = None, 0
        for _ in range(lm_runs):
            start = time.perf_counter()
            lm_centre, evaluations = ardupilot_lm(samples)
            lm_times.append(time.perf_counter() - start)
        results[str(n)] = {
            "median_s": statistics.median(times),
            "runs": runs,
            "hard_iron_ut": [float(v) for v in centre],
            "lm_median_s": statistics.median(lm_times),
            "lm_runs": lm_runs,
            "lm_evaluations": int(evaluations),
            "lm_hard_iron_ut": [float(v) for v in lm_centre],
        }
    import scipy
    json.dump({"numpy": np.__version__, "scipy": scipy.__version__, "fits": results}, sys.stdout, indent=2)
    print()


if __name__ == "__main__":
    main()
