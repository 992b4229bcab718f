"""The EKF peers of benches/pdr.rs: the PDR paper's [E, N, l, a] filter (Eq. 13) with
filterpy's ExtendedKalmanFilter and as a plain numpy loop, on the same steps, start and
noise as compass-pdr's PdrEkf::step.

Reads target/bench-data/pdr_steps.f64 (little-endian float64 pairs: step length in m,
measured heading in rad in [0, 2pi)), pdr_settings.json (start and noise) and
pdr_native.json (compass-pdr's state after several step counts), all written by the
Rust benchmark. Per step, exactly what PdrEkf::step does:

1. update with z = [l, a] (H selects l and a, R = diag(sigma_l_meas^2,
   sigma_a_meas^2)), the heading innovation wrapped to (-pi, pi], then the heading
   state wrapped to [0, 2pi);
2. predict: x <- f(x) (E += l sin a, N += l cos a), P <- F P F^T + Q with
   F = I + [0 0 sin a  l cos a; 0 0 cos a  -l sin a; 0; 0] and Q = diag(0, 0,
   sigma_l_walk^2, sigma_a_walk^2).

filterpy updates P in Joseph form and compass-pdr as P - K S K^T symmetrised: the same
in exact arithmetic, so the final states agree to rounding (printed).

Prints, as JSON, steps/s (median of RUNS runs of N_STEPS steps each) and the largest
difference from compass-pdr's state after the same number of steps.
"""
import json
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

import filterpy
from filterpy.kalman import ExtendedKalmanFilter

N_STEPS = 50_000
RUNS = 3
TAU = 2.0 * math.pi


def wrap_to_2pi(angle):
    """compass-pdr's angle::wrap_to_2pi: Python's % is rem_euclid for a positive
    divisor."""
    wrapped = angle % TAU
    return 0.0 if wrapped >= TAU else wrapped


def wrap_to_pi(angle):
    wrapped = wrap_to_2pi(angle)
    return wrapped - TAU if wrapped > math.pi else wrapped


class Model:
    """The filter's start and noise, from pdr_settings.json."""

    def __init__(self, settings, first):
        noise = settings["noise"]
        self.q = np.diag([0.0, 0.0, noise["step_length_walk_m"] ** 2, noise["heading_walk_rad"] ** 2])
        self.r = np.diag([noise["step_length_measurement_m"] ** 2, noise["heading_measurement_rad"] ** 2])
        east, north = settings["start_en_m"]
        self.x0 = np.array([east, north, first[0], wrap_to_2pi(first[1])])
        sigma = settings["start_sigma_m"]
        self.p0 = np.diag([sigma**2, sigma**2, self.r[0, 0], self.r[1, 1]])


H = np.array([[0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


def jacobian_f(x):
    l, a = x[2], x[3]
    f = np.eye(4)
    f[0, 2] = math.sin(a)
    f[0, 3] = l * math.cos(a)
    f[1, 2] = math.cos(a)
    f[1, 3] = -l * math.sin(a)
    return f


class PdrFilter(ExtendedKalmanFilter):
    """filterpy's EKF with Eq. 13's nonlinear state transition."""

    def predict_x(self, u=0):
        l, a = self.x[2, 0], self.x[3, 0]
        self.x[0, 0] += l * math.sin(a)
        self.x[1, 0] += l * math.cos(a)


def h_jacobian(x):
    return H


def hx(x):
    return x[2:4]


def residual(z, z_predicted):
    y = z - z_predicted
    y[1, 0] = wrap_to_pi(y[1, 0])
    return y


def run_filterpy(model, zs):
    ekf = PdrFilter(dim_x=4, dim_z=2)
    ekf.x = model.x0.reshape(4, 1).copy()
    ekf.P = model.p0.copy()
    ekf.R = model.r
    ekf.Q = model.q
    for z in zs:
        ekf.update(z, h_jacobian, hx, residual=residual)
        ekf.x[3, 0] = wrap_to_2pi(ekf.x[3, 0])
        ekf.F = jacobian_f(ekf.x[:, 0])
        ekf.predict()
    return ekf.x[:, 0], ekf.P


def run_numpy(model, zs):
    x = model.x0.copy()
    p = model.p0.copy()
    r, q = model.r, model.q
    eye = np.eye(4)
    for z in zs:
        y = z - H @ x
        y[1] = wrap_to_pi(y[1])
        s = H @ p @ H.T + r
        k = p @ H.T @ np.linalg.inv(s)
        x = x + k @ y
        p = (eye - k @ H) @ p
        p = 0.5 * (p + p.T)
        x[3] = wrap_to_2pi(x[3])
        f = jacobian_f(x)
        l, a = x[2], x[3]
        x[0] += l * math.sin(a)
        x[1] += l * math.cos(a)
        p = f @ p @ f.T + q
    return x, p


def timed(run, model, zs):
    times = []
    for _ in range(RUNS):
        start = time.perf_counter()
        x, p = run(model, zs)
        times.append(time.perf_counter() - start)
    return times, x, p


def main():
    data_dir = Path(sys.argv[1] if len(sys.argv) > 1 else "target/bench-data")
    settings = json.loads((data_dir / "pdr_settings.json").read_text())
    native = json.loads((data_dir / "pdr_native.json").read_text())
    steps = np.fromfile(data_dir / "pdr_steps.f64", dtype="<f8").reshape(-1, 2)
    n_steps = min(N_STEPS, len(steps))
    if str(n_steps) not in native["checkpoints"]:
        raise SystemExit(f"pdr_native.json has no state after {n_steps} steps")
    ours = native["checkpoints"][str(n_steps)]
    ours_x, ours_p = np.array(ours["x"]), np.array(ours["p"])
    model = Model(settings, steps[0])
    result = {
        "filterpy_version": filterpy.__version__,
        "numpy_version": np.__version__,
        "python": sys.version.split()[0],
        "n_steps": n_steps,
        "runs": RUNS,
    }
    for name, run, zs in [
        ("filterpy_ekf", run_filterpy, steps[:n_steps].reshape(-1, 2, 1)),
        ("numpy_loop", run_numpy, steps[:n_steps]),
    ]:
        times, x, p = timed(run, model, zs)
        median_s = statistics.median(times)
        result[name] = {
            "times_s": times,
            "median_s": median_s,
            "steps_per_s": n_steps / median_s,
            "us_per_step": median_s / n_steps * 1e6,
            "x": x.tolist(),
            "max_abs_diff_x": float(np.max(np.abs(x - ours_x))),
            "max_abs_diff_p": float(np.max(np.abs(p - ours_p))),
        }
    json.dump(result, sys.stdout, indent=2)
    print()


if __name__ == "__main__":
    main()
