"""The MLP-training peer of benches/mlp.rs: scikit-learn's MLPRegressor with the lbfgs
solver on the same samples, architecture, loss and stopping rules.

Reads target/bench-data/mlp_samples.f64 (little-endian float64 rows: 5 inputs then the
target; the first n_train rows train, the rest test) and mlp_settings.json (both
written by the Rust benchmark). Inputs and target are standardised with the training
rows' mean and population standard deviation, as compass-pdr's model does, so both
minimise the same objective: squared error / 2 over samples plus alpha * |W|^2 / (2 n).
Prints, as JSON, the median training time of 5 fits (standardisation included), the
iterations run and the training and test MSE in the target's raw units.
"""
import json
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import sklearn
from sklearn.exceptions import ConvergenceWarning
from sklearn.neural_network import MLPRegressor

RUNS = 5


def fit(x_train, y_train, settings):
    x_mean, x_std = x_train.mean(axis=0), x_train.std(axis=0)
    x_std[x_std == 0] = 1.0
    y_mean, y_std = y_train.mean(), y_train.std()
    model = MLPRegressor(
        hidden_layer_sizes=(settings["hidden"],),
        activation=settings["activation"],
        solver="lbfgs",
        alpha=settings["alpha"],
        max_iter=settings["max_iter"],
        tol=settings["tol"],
        random_state=settings["random_state"],
    )
    model.fit((x_train - x_mean) / x_std, (y_train - y_mean) / y_std)
    return lambda x: model.predict((x - x_mean) / x_std) * y_std + y_mean, model


def main():
    data_dir = Path(sys.argv[1] if len(sys.argv) > 1 else "target/bench-data")
    settings = json.loads((data_dir / "mlp_settings.json").read_text())
    width = settings["n_inputs"] + 1
    rows = np.fromfile(data_dir / "mlp_samples.f64", dtype="<f8").reshape(-1, width)
    n_train = settings["n_train"]
    x_train, y_train = rows[:n_train, :-1].copy(), rows[:n_train, -1].copy()
    x_test, y_test = rows[n_train:, :-1].copy(), rows[n_train:, -1].copy()
    times = []
    for _ in range(RUNS):
        with warnings.catch_warnings():
            # Stopping at max_iter is expected, as for compass-pdr.
            warnings.simplefilter("ignore", ConvergenceWarning)
            start = time.perf_counter()
            predict, model = fit(x_train, y_train, settings)
            times.append(time.perf_counter() - start)
    result = {
        "sklearn": sklearn.__version__,
        "numpy": np.__version__,
        "runs": RUNS,
        "times_s": times,
        "median_s": statistics.median(times),
        "n_iter": int(model.n_iter_),
        "final_loss": float(model.loss_),
        "train_mse": float(np.mean((predict(x_train) - y_train) ** 2)),
        "test_mse": float(np.mean((predict(x_test) - y_test) ** 2)),
        "n_train": n_train,
        "n_test": len(y_test),
    }
    json.dump(result, sys.stdout, indent=2)
    print()


if __name__ == "__main__":
    main()
