#!/usr/bin/env python3
"""The gyroscope's bias the TYREX trials' motion capture shows: an external truth for
the bias `attitude::down::gyro_bias` estimates from how the gyroscope's turns carry
down along.

Usage:
    gyro_bias_truth.py TRIAL_DIR... [--json OUT.json]

For each trial (the files and frames of attitude_peers.py: the mocap rigid body's axes
are the device's), the body's rate from the mocap, log(R(t)ᵀ·R(t + 0.2 s)) / 0.2 s, is
set beside the mean of gyroscope-calibrated.txt over the same 0.2 s, on the phone's
clock (timeAlignment.txt) shifted by the lag within ±0.1 s that fits best; frames
the authors flagged as mocap errors are left out, and steps across them. The bias is
the mean difference (device axes, rad/s); its spread over 30 s pieces and the RMS of
what is left say how far to trust it: a few mrad/s where the phone is held (texting,
the swinging and pocket trials), nothing where it runs (the rates reach the
gyroscope's range and the marker's jitter is large). It is printed in compass-pdr's
body axes too (attitude_peers.body_from_device, the rule of src/io/axes.rs).
"""

import argparse
import json
import pathlib
import sys

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import attitude_peers as peers  # noqa: E402

STEP_S = 0.2
PIECE_S = 30.0
LAGS_S = np.arange(-0.1, 0.1001, 0.01)
# Frames either side of a step more than this apart (a hole in the tracking) skip it.
MAX_HOLE_S = 0.05


def rates(trial, name, lag_s):
    """Times, mocap body rates and gyroscope mean rates (device axes, rad/s)."""
    t_mocap, matrices = trial["mocap"]
    valid = ~np.isnan(matrices).any(axis=(1, 2))
    for start, end in peers.MOCAP_BAD_INTERVALS.get(name, []):
        valid &= ~((t_mocap >= start) & (t_mocap <= end))
    t_valid = t_mocap[valid] - trial["time_diff"] + lag_s
    slerp = Slerp(t_valid, Rotation.from_matrix(matrices[valid]))
    t = np.arange(t_valid[0] + 1.0, t_valid[-1] - 1.0, STEP_S)
    lo = np.searchsorted(t_valid, t)
    hi = np.searchsorted(t_valid, t + STEP_S)
    ok = (lo > 0) & (hi < len(t_valid))
    ok[ok] &= t_valid[hi[ok]] - t_valid[lo[ok] - 1] < STEP_S + MAX_HOLE_S
    gyr = trial["gyr"]
    inside = (t >= gyr[0, 0]) & (t + STEP_S <= gyr[-1, 0])
    t = t[ok & inside]
    mocap = (slerp(t).inv() * slerp(t + STEP_S)).as_rotvec() / STEP_S
    angle = np.concatenate([np.zeros((1, 3)), np.cumsum(gyr[:-1, 1:4] * np.diff(gyr[:, 0])[:, None], axis=0)])
    turned = np.column_stack(
        [np.interp(t + STEP_S, gyr[:, 0], angle[:, j]) - np.interp(t, gyr[:, 0], angle[:, j]) for j in range(3)]
    )
    return t, mocap, turned / STEP_S


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("trials", nargs="+", type=pathlib.Path)
    parser.add_argument("--json", type=pathlib.Path)
    args = parser.parse_args()
    out = []
    print("| trial | lag (s) | bias, device axes (mrad/s) | bias, body axes (mrad/s) | mount | spread over 30 s pieces (mrad/s) | residual RMS (rad/s) |")
    print("|---|---|---|---|---|---|---|")
    for folder in args.trials:
        name = folder.resolve().name
        trial = peers.load_trial(folder, name)
        best = None
        for lag_s in LAGS_S:
            t, mocap, gyro = rates(trial, name, lag_s)
            difference = gyro - mocap
            bias = difference.mean(axis=0)
            rms = float(np.sqrt(((difference - bias) ** 2).mean()))
            if best is None or rms < best[0]:
                best = (rms, lag_s, bias, t, difference)
        rms, lag_s, bias, t, difference = best
        pieces = [
            difference[(t >= start) & (t < start + PIECE_S)].mean(axis=0)
            for start in np.arange(t[0], t[-1] - PIECE_S / 2, PIECE_S)
        ]
        spread = float(np.max(np.linalg.norm(np.array(pieces) - bias, axis=1))) if pieces else float("nan")
        mount, _, _ = peers.detect_mount(trial["acc"])
        in_body = peers.body_from_device(mount, bias)
        fmt = lambda v: ", ".join(f"{1000 * x:+.1f}" for x in v)  # noqa: E731
        print(f"| {name} | {lag_s:+.2f} | {fmt(bias)} | {fmt(in_body)} | {mount} | {1000 * spread:.1f} | {rms:.3f} |")
        out.append(
            {
                "trial": name,
                "lag_s": round(float(lag_s), 3),
                "bias_device_radps": bias.round(5).tolist(),
                "bias_body_radps": in_body.round(5).tolist(),
                "mount": mount,
                "spread_radps": round(spread, 5),
                "residual_rms_radps": round(rms, 4),
            }
        )
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
