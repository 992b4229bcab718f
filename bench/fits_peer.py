"""The peers of benches/fits.rs on the same samples (10⁴ magnetometer samples of each real
log, written by the Rust benchmark as target/bench-data/fits_<case>.f64): numpy's
Li-Griffiths algebraic ellipsoid fit and the ArduPilot-style two-step Levenberg-Marquardt
fit with scipy.optimize.least_squares(method="lm") of bench/ellipsoid_peer.py. Neither
uses the accelerometer or a prior: they are the fastest well-known ways to get a 3D hard
and soft iron from the same samples, not the same estimator as ours.

Prints, as JSON, each case's median time (7 runs of each) and the hard iron found.
"""
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import scipy

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ellipsoid_peer import ardupilot_lm, li_griffiths  # noqa: E402

RUNS = 7


def timed(function):
    times, result = [], None
    for _ in range(RUNS):
        start = time.perf_counter()
        result = function()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def main():
    data_dir = Path(sys.argv[1] if len(sys.argv) > 1 else "target/bench-data")
    cases = {}
    for path in sorted(data_dir.glob("fits_*.f64")):
        samples = np.fromfile(path, dtype="<f8").reshape(-1, 3)
        x, y, z = samples[:, 0].copy(), samples[:, 1].copy(), samples[:, 2].copy()
        entry = {"n": len(samples)}
        try:
            seconds, (centre, _, _) = timed(lambda: li_griffiths(x, y, z))
            entry["numpy_median_s"] = seconds
            entry["numpy_hard_iron"] = [float(v) for v in np.real(centre)]
        except (np.linalg.LinAlgError, ValueError) as error:
            entry["numpy_error"] = str(error)
        try:
            seconds, (centre, evaluations) = timed(lambda: ardupilot_lm(samples))
            entry["scipy_lm_median_s"] = seconds
            entry["scipy_lm_hard_iron"] = [float(v) for v in centre]
            entry["scipy_lm_evaluations"] = int(evaluations)
        except (np.linalg.LinAlgError, ValueError) as error:
            entry["scipy_lm_error"] = str(error)
        cases[path.stem[len("fits_"):]] = entry
    json.dump({"numpy": np.__version__, "scipy": scipy.__version__, "cases": cases}, sys.stdout, indent=2)
    print()


if __name__ == "__main__":
    main()
