#!/usr/bin/env python3
"""Heading accuracy of attitude filters against motion-capture truth on the TYREX
attitude benchmark (Michel et al., "On Attitude Estimation with Smartphones",
tyrex-team/benchmarks-attitude-smartphones), for docs/BENCHMARKS.md.

Usage:
    attitude_peers.py DATA_DIR... [--ours DIR] [--json OUT.json] [--truth-out DIR]

DATA_DIR holds one folder per trial (the five Thibaud_Nexus5_* trials listed in
TRIALS), each with the phone's sensor files and the Qualisys ground truth. Prints a
markdown table (RMS heading error per method and trial) and a frame-check table, and
writes every figure, with the peers' processing times, to OUT.json when asked.

Files (headerless, space separated, t in seconds on the phone clock)
---------------------------------------------------------------------
accelerometer.txt (t ax ay az, m/s², specific force: +9.81 on z face up at rest),
gyroscope-calibrated.txt (t x y z, rad/s, the OS's drift estimate removed),
magnetometer-calibrated.txt (t x y z, µT, the OS's hard iron removed),
rotation-vector.txt (t x y z w ...: Android's rotation vector), timeAlignment.txt
(timeDiff), qualisys_groundtruth_<trial>.mat (MATLAB v5).

Frames (each checked on the data; see the frame-check table the script prints)
------------------------------------------------------------------------------
* Device: Android axes, x right of the screen, y towards the top edge, z out of the
  screen.
* Mocap: the .mat holds one struct named after the trial; RigidBodies.Rotations is
  1×9×N, one rotation matrix per 60 Hz frame, column-major (MATLAB reshape(r, 3, 3)).
  That matrix R maps rigid-body axes to the mocap room: v_room = R · v_body (the
  authors' loader takes dcm2quat(R'), i.e. the room-to-body DCM). The room's z axis is
  vertical, up; x and y are horizontal with an arbitrary north. The rigid body's axes
  ARE the device axes (the axis mapping is the identity, no signed permutation): with
  R and the identity, Rᵀ·ẑ lines up with the low-passed accelerometer direction with a
  mean cosine of 0.95-1.00 on all five trials, and no other combination of matrix
  direction, vertical axis and signed permutation does (the transposed matrix fits
  only the two texting trials, where the phone stays nearly level). With these
  conventions the rotation vector's heading agrees with the mocap's within 3.8° RMS
  (NoDist_Texting, body x) and 5.2° (NoDist_RunningHand, full-attitude yaw), as the
  published medians of ~4-6° for the undisturbed rotation vector lead one to expect.
  Frames with NaN (tracking lost) are skipped, and so are the intervals the authors
  flagged by hand as mocap errors in AttitudeBenchmarks.m (MOCAP_BAD_INTERVALS: on
  FrontPocket the marker labels swap between 40 s and 52.6 s and the "truth" flips by
  up to 177° from one frame to the next).
* Android's rotation vector: the quaternion (x, y, z, w) rotates device axes into
  ENU (x east, y north, z up): v_enu = R(q) · v_device.
* Fusion (imufusion) in its NWU convention and ahrs' Madgwick (its earth frame is NWU
  too, whatever its docstring says: the reference field is (bx, 0, bz), gravity +z
  as specific force, and its start ecompass(frame='NED') returns rows (north, west,
  up)): the quaternion (w, x, y, z) rotates sensor axes into the earth frame.
* Heading of a world vector v = angle of its horizontal part clockwise from north:
  atan2(E, N) in ENU, atan2(-W, N) in NWU, atan2(x, y) in the mocap room (any fixed
  north will do: one constant offset per trial and method is removed).

Body axis (the rule of src/io/axes.rs)
--------------------------------------
f = mean specific force of the whole accelerometer file, device axes. If |f.z| is the
largest the mount is FLAT and body x (forward) = device +y; else if |f.y| > |f.x| it is
UPRIGHT and body x = device -z; otherwise the phone is on its side (Dist_Swinging and
NoDist_RunningHand: |f.x| is the largest) and compass-pdr assumes it held FLAT, so
body x = device +y there too (the mount column says "side → flat"). The heading compared is that
of body x. Where the truth's body x is within NEAR_VERTICAL_DEG of the vertical the
heading means nothing: those mocap frames are excluded, for every method, and
counted.

Time alignment and scored frames
--------------------------------
t_mocap = t_phone + timeDiff (the authors' AcquisitionData.offsetTimeAllData), mocap
frame i at t_mocap = i / 60 s. The sign checks out: the gyroscope's rates match the
mocap's angular rates best 20-25 ms from that shift (the residual lag of the frame
check), and several times worse with the opposite sign. A frame is scored when it
is valid, falls inside the phone log (the common time base below) after its first
CONVERGENCE_S seconds and not in a gap of the log longer than MAX_GAP_S, and its body
x is not near vertical. Every method is scored on the same
frames (ours too, unless its CSV lacks some: then it is scored on fewer, and the count
is reported).

Metric
------
Each method's heading is interpolated circularly (unwrapped, linear) at the scored
mocap times; error = wrap(method - truth); the one constant offset that minimises the
RMS (the circular mean of the error, refined by the mean of the wrapped residuals) is
removed; the figure is the RMS of what is left, in degrees.

Methods (same samples for all)
------------------------------
Common time base: the gyroscope-calibrated sample times, from the first one at which
an accelerometer and a magnetometer sample exist; the accelerometer and magnetometer
are held causally (the latest sample at or before each gyro time, as a live filter
sees them); dt from successive gyro times (the nominal period across a gap longer than
MAX_GAP_S: the attitude is held over lost data). Each filter starts at the first
sample of that base.
1. rotation_vector: Android's own fused attitude (rotation-vector.txt), its own times.
2. fusion: imufusion 1.3.3 (xioTechnologies Fusion), the advanced example's settings:
   AhrsSettings(sample_rate, CONVENTION_NWU, gain 0.5, gyroscope_range 2000 deg/s,
   acceleration_rejection 10°, magnetic_rejection 10°, rejection_timeout 5 s) - in
   1.3.x the timeout is in seconds (the C library multiplies it by the sample rate),
   and at 0 (the default) both rejections are off; Bias (the old Offset) with its
   defaults (3 deg/s, 3 s) on the gyro; set_sample_period(dt) then update(gyro deg/s,
   accel g, mag µT) per sample.
3. madgwick: ahrs 0.4.0 ahrs.filters.Madgwick, MARG, its default MARG gain 0.041
   (gain_marg; a filter built without data would take the IMU gain 0.033), started
   from ecompass(acc, mag, frame='NED') as its batch mode does, then
   updateMARG(q, gyr rad/s, acc m/s², mag µT, dt) per sample.
4. gyro: the gyroscope alone, a reference and not a peer: q_k = q_(k-1) ⊗ exp(ω_k dt_k / 2)
   from the rotation vector's attitude at the first sample.
5. ours (--ours DIR): DIR/<trial>.csv, '#' comments, header
   t_s,yaw_deg,pitch_deg,roll_deg,yaw_sigma_deg, t_s on the phone clock, yaw_deg the
   heading of body x clockwise from north; rows without a yaw are skipped. The median
   yaw_sigma_deg over the rows inside the scored time span is reported too.

The processing loops of fusion, madgwick and gyro are timed (wall clock, samples/s);
the rotation vector is the phone's output and costs nothing here.
"""

import argparse
import csv
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import scipy.io
from scipy.spatial.transform import Rotation, Slerp

import imufusion
from ahrs.common.orientation import ecompass
from ahrs.filters import Madgwick
from vqf import VQF, offlineVQF

TRIALS = [
    "Thibaud_Nexus5_Dist_FrontPocket",
    "Thibaud_Nexus5_Dist_Swinging",
    "Thibaud_Nexus5_Dist_Texting",
    "Thibaud_Nexus5_NoDist_RunningHand",
    "Thibaud_Nexus5_NoDist_Texting",
    # ../shared/data/tyrex-attitude-more (issue 43)
    "Thibaud_Nexus5_Dist_BackPocket",
    "Thibaud_Nexus5_Dist_Phoning",
    "Thibaud_Nexus5_NoDist_RunningPocket",
    "Thibaud_Nexus5_NoDist_Swinging",
]

# Mocap errors the authors flagged by hand (mocap seconds), from loadDatasets in
# src/Benchmark/AttitudeBenchmarks.m of tyrex-team/benchmarks-attitude-smartphones.
MOCAP_BAD_INTERVALS = {
    "Thibaud_Nexus5_Dist_FrontPocket": [(40.0, 52.6)],
    "Thibaud_Nexus5_Dist_Swinging": [(105.45, 105.5)],
}

# VQF's earth frame: z up, x towards the horizontal field (checked on the data: with "enu"
# its heading follows the mocap's within a few degrees on NoDist_Texting).
VQF_FRAME = "nwu"

MOCAP_RATE_HZ = 60.0
CONVERGENCE_S = 5.0  # skipped after the phone log starts, for every method
NEAR_VERTICAL_DEG = 20.0  # body x closer than this to the vertical: no heading
MAX_GAP_S = 0.1  # a longer hole in the phone log is lost data
G = 9.80665  # m/s² per g, for imufusion's accelerometer unit

PEERS = ["rotation_vector", "fusion", "madgwick", "vqf", "vqf_offline"]
METHODS = PEERS + ["gyro"]


# --------------------------------------------------------------------------- loading


def load_table(path, columns):
    """The first `columns` columns of a headerless, space-separated text file."""
    return np.loadtxt(path, ndmin=2)[:, :columns]


def load_mocap(path, trial):
    """Mocap frame times (mocap clock) and rigid-body-to-room matrices; NaN if lost."""
    mat = scipy.io.loadmat(path)
    # The struct is named after the trial, not always in the same case
    # (Thibaud_Nexus5_Dist_phoning).
    names = [key for key in mat if key.lower() == trial.lower()]
    struct = mat[names[0] if names else trial][0, 0]
    body = struct["RigidBodies"][0, 0]
    rotations = body["Rotations"][0]  # 9 × N, one column-major 3×3 matrix per frame
    n = rotations.shape[1]
    rate = float(np.squeeze(struct["FrameRate"]))
    assert rate == MOCAP_RATE_HZ, rate
    # reshape(r, 3, 3) in MATLAB fills columns first: r[0:3] is the first column.
    matrices = rotations.T.reshape(n, 3, 3).transpose(0, 2, 1)
    return np.arange(n) / rate, matrices


def load_trial(folder, trial):
    return {
        "acc": load_table(folder / "accelerometer.txt", 4),
        "gyr": load_table(folder / "gyroscope-calibrated.txt", 4),
        "mag": load_table(folder / "magnetometer-calibrated.txt", 4),
        "rv": load_table(folder / "rotation-vector.txt", 5),
        "time_diff": float((folder / "timeAlignment.txt").read_text().split()[0]),
        "mocap": load_mocap(folder / f"qualisys_groundtruth_{trial}.mat", trial),
    }


def load_ours(path):
    """Times, yaw (deg) and yaw sigma (deg) of our CSV; rows without a yaw dropped."""
    rows = []
    with open(path, newline="") as handle:
        lines = (line for line in handle if line.strip() and not line.lstrip().startswith("#"))
        for row in csv.DictReader(lines):
            def number(key):
                try:
                    return float(row.get(key) or "nan")
                except ValueError:
                    return math.nan
            rows.append((number("t_s"), number("yaw_deg"), number("yaw_sigma_deg")))
    data = np.array(rows, dtype=float).reshape(-1, 3)
    data = data[np.isfinite(data[:, 0]) & np.isfinite(data[:, 1])]
    data = data[np.argsort(data[:, 0], kind="stable")]
    return data[:, 0], data[:, 1], data[:, 2]


# ------------------------------------------------------------------- frames and axes


def detect_mount(acc):
    """("flat" | "upright" | "side → flat", body x in device axes, mean force).

    On its side compass-pdr cannot tell the mount and assumes it flat."""
    f = acc[:, 1:4].mean(axis=0)
    if abs(f[2]) >= abs(f[1]) and abs(f[2]) >= abs(f[0]):
        return "flat", np.array([0.0, 1.0, 0.0]), f
    if abs(f[1]) > abs(f[0]):
        return "upright", np.array([0.0, 0.0, -1.0]), f
    return "side → flat", np.array([0.0, 1.0, 0.0]), f


def body_from_device(mount, v):
    """A device-axes vector in compass-pdr's body axes (x forward, y right, z down) for
    a mount of detect_mount (src/io/axes.rs: flat, and on its side taken as flat, x =
    device y, y = device x, z = -device z; upright x = -device z, y = device x, z =
    -device y)."""
    if mount == "upright":
        return np.array([-v[2], v[0], -v[1]])
    return np.array([v[1], v[0], -v[2]])


def heading_deg(v, frame):
    """Heading (deg, clockwise from north) of world vectors v (N × 3)."""
    if frame == "nwu":
        return np.degrees(np.arctan2(-v[:, 1], v[:, 0]))
    # ENU, and the mocap room (x, y horizontal, z up) taken as if it were ENU
    return np.degrees(np.arctan2(v[:, 0], v[:, 1]))


def wrap_deg(angle):
    return (np.asarray(angle) + 180.0) % 360.0 - 180.0


def quaternions_wxyz_to_matrices(q):
    return Rotation.from_quat(np.asarray(q)[:, [1, 2, 3, 0]]).as_matrix()


def rotation_vector_quaternions(rv):
    """Android's rotation vector as (w, x, y, z), w rebuilt when the file lacks it."""
    xyz = rv[:, 1:4]
    if rv.shape[1] >= 5:
        w = rv[:, 4]
    else:
        w = np.sqrt(np.clip(1.0 - np.sum(xyz**2, axis=1), 0.0, None))
    return np.column_stack([w, xyz])


# ----------------------------------------------------------------- common time base


def common_base(trial):
    """Gyro times with acc and mag held causally (zero-order hold), and dt."""
    gyr, acc, mag = trial["gyr"], trial["acc"], trial["mag"]
    start = max(gyr[0, 0], acc[0, 0], mag[0, 0])
    gyr = gyr[gyr[:, 0] >= start]
    t = gyr[:, 0]
    acc_index = np.searchsorted(acc[:, 0], t, side="right") - 1
    mag_index = np.searchsorted(mag[:, 0], t, side="right") - 1
    steps = np.diff(t)
    nominal = float(np.median(steps))
    dt = np.concatenate([[nominal], steps])
    gaps = dt > MAX_GAP_S
    dt[gaps] = nominal  # hold the attitude across lost data
    return {
        "t": t,
        "gyr": gyr[:, 1:4],
        "acc": acc[acc_index, 1:4],
        "mag": mag[mag_index, 1:4],
        "dt": dt,
        "rate_hz": 1.0 / nominal,
        "gap_starts": t[np.flatnonzero(gaps) - 1],
        "gap_ends": t[gaps],
    }


# ------------------------------------------------------------------------- methods


def timed(function, *args):
    start = time.perf_counter()
    result = function(*args)
    return result, time.perf_counter() - start


def fusion_loop(base, with_states=False):
    """imufusion's AHRS over the base: quaternions (w, x, y, z), NWU."""
    rate = base["rate_hz"]
    ahrs = imufusion.Ahrs()
    ahrs.set_settings(
        imufusion.AhrsSettings(
            sample_rate=rate,
            convention=imufusion.CONVENTION_NWU,
            gain=0.5,
            gyroscope_range=2000.0,
            acceleration_rejection=10.0,
            magnetic_rejection=10.0,
            rejection_timeout=5.0,  # seconds in 1.3.x (× sample rate inside)
        )
    )
    bias = imufusion.Bias()
    bias.set_settings(imufusion.BiasSettings(sample_rate=rate, stationary_threshold=3.0, stationary_period=3.0))
    gyr = np.degrees(base["gyr"])
    acc = base["acc"] / G
    mag = base["mag"]
    dt = base["dt"]
    n = len(dt)
    out = np.empty((n, 4))
    ignored = np.zeros((n, 2), dtype=bool)
    for k in range(n):
        ahrs.set_sample_period(dt[k])
        ahrs.update(bias.update(gyr[k]), acc[k], mag[k])
        out[k] = ahrs.get_quaternion()
        if with_states:
            states = ahrs.get_internal_states()
            ignored[k] = states.accelerometer_ignored, states.magnetometer_ignored
    return (out, ignored) if with_states else out


def madgwick_loop(base):
    """ahrs' Madgwick MARG filter over the base: quaternions (w, x, y, z), NWU."""
    filt = Madgwick(frequency=base["rate_hz"])
    filt.gain = filt.gain_marg  # built without data it would take the IMU gain
    gyr, acc, mag, dt = base["gyr"], base["acc"], base["mag"], base["dt"]
    n = len(dt)
    out = np.empty((n, 4))
    q = ecompass(acc[0], mag[0], frame="NED", representation="quaternion")
    out[0] = q
    for k in range(1, n):
        q = filt.updateMARG(q, gyr=gyr[k], acc=acc[k], mag=mag[k], dt=dt[k])
        out[k] = q
    return out


def vqf_offline_loop(base):
    """VQF's offline variant (offlineVQF, the same package and defaults): it reads the
    whole log, future samples included, as compass-pdr's attitude export does (its
    forward and backward runs, src/attitude/smoother.rs), so it is the like-for-like
    peer of that export; the others are causal filters."""
    out = offlineVQF(
        np.ascontiguousarray(base["gyr"], dtype=float),
        np.ascontiguousarray(base["acc"], dtype=float),
        np.ascontiguousarray(base["mag"], dtype=float),
        1.0 / base["rate_hz"],
    )
    return out["quat9D"]


def vqf_loop(base):
    """VQF (vqf 2.1.2, Laidig & Seel 2023) with its default parameters, magnetic
    disturbance rejection on, over the base at its nominal rate: 9D quaternions
    (w, x, y, z), sensor to an ENU-like earth frame (z up; its north is the field's)."""
    ts = 1.0 / base["rate_hz"]
    filt = VQF(ts)
    out = filt.updateBatch(
        np.ascontiguousarray(base["gyr"], dtype=float),
        np.ascontiguousarray(base["acc"], dtype=float),
        np.ascontiguousarray(base["mag"], dtype=float),
    )
    return out["quat9D"]


def gyro_loop(base, q0):
    """The gyroscope alone, q_k = q_(k-1) ⊗ exp(ω_k dt_k / 2), from q0 (w, x, y, z)."""
    w, x, y, z = (float(c) for c in q0)
    gyr = base["gyr"].tolist()
    dt = base["dt"].tolist()
    out = np.empty((len(dt), 4))
    out[0] = w, x, y, z
    for k in range(1, len(dt)):
        gx, gy, gz = gyr[k]
        half = 0.5 * dt[k]
        angle = math.sqrt(gx * gx + gy * gy + gz * gz) * half
        if angle > 0.0:
            s = math.sin(angle) / angle * half
            dw, dx, dy, dz = math.cos(angle), gx * s, gy * s, gz * s
            w, x, y, z = (
                w * dw - x * dx - y * dy - z * dz,
                w * dx + x * dw + y * dz - z * dy,
                w * dy - x * dz + y * dw + z * dx,
                w * dz + x * dy - y * dx + z * dw,
            )
        out[k] = w, x, y, z
    return out


def rotation_vector_at(rv, t):
    """Android's attitude (w, x, y, z) at times t, by slerp."""
    q = rotation_vector_quaternions(rv)
    slerp = Slerp(rv[:, 0], Rotation.from_quat(q[:, [1, 2, 3, 0]]))
    return slerp(np.clip(t, rv[0, 0], rv[-1, 0])).as_quat()[:, [3, 0, 1, 2]]


# ------------------------------------------------------------------------- scoring


def interpolate_heading(t_method, heading, t, max_bracket_s):
    """Circular (unwrapped, linear) interpolation; NaN outside or across holes."""
    unwrapped = np.degrees(np.unwrap(np.radians(heading)))
    out = wrap_deg(np.interp(t, t_method, unwrapped))
    after = np.searchsorted(t_method, t, side="right")
    before = after - 1  # the last sample at or before t
    after = np.minimum(after, len(t_method) - 1)
    ok = (before >= 0) & (t <= t_method[-1])
    ok &= t_method[after] - t_method[np.maximum(before, 0)] <= max_bracket_s
    out[~ok] = np.nan
    return out


def offset_removed_rms(error_deg):
    """RMS (deg) after removing the constant offset minimising it, and that offset."""
    e = np.radians(error_deg)
    offset = math.atan2(np.mean(np.sin(e)), np.mean(np.cos(e)))
    for _ in range(3):  # the circular mean, refined to the L2 minimiser
        offset += np.mean(np.angle(np.exp(1j * (e - offset))))
    residual = np.degrees(np.angle(np.exp(1j * (e - offset))))
    return float(np.sqrt(np.mean(residual**2))), float(np.degrees(offset))


def score(t_scored, truth, t_method, heading, max_bracket_s=0.5):
    h = interpolate_heading(t_method, heading, t_scored, max_bracket_s)
    ok = np.isfinite(h)
    if not ok.any():
        return {"rms_deg": None, "offset_deg": None, "frames": 0}
    rms, offset = offset_removed_rms(wrap_deg(h[ok] - truth[ok]))
    return {"rms_deg": rms, "offset_deg": offset, "frames": int(ok.sum())}


def sigma_coverage(t_scored, truth, t_method, heading, sigma, max_bracket_s=0.5):
    """Shares of the frames whose error (the trial's constant offset removed) is within
    1 and 2 x the stated yaw sigma at that time: a sigma that holds covers ~68 / 95 %.
    The offset removed (the mocap room's north) makes the errors, and so the shares,
    if anything smaller than the filter's own absolute error."""
    h = interpolate_heading(t_method, heading, t_scored, max_bracket_s)
    s = np.interp(t_scored, t_method, sigma)
    ok = np.isfinite(h) & np.isfinite(s)
    if not ok.any():
        return {"within_1_sigma_pct": None, "within_2_sigma_pct": None}
    _, offset = offset_removed_rms(wrap_deg(h[ok] - truth[ok]))
    residual = np.abs(wrap_deg(h[ok] - truth[ok] - offset))
    return {
        "within_1_sigma_pct": float(100.0 * np.mean(residual <= s[ok])),
        "within_2_sigma_pct": float(100.0 * np.mean(residual <= 2.0 * s[ok])),
    }


# ------------------------------------------------------------------- frame checks


def frame_check(trial, base, t_phone, matrices, valid):
    """The conventions, checked on the data, whatever the mount.

    D = R_rv · R_mocapᵀ maps the mocap room into ENU and must be one constant
    rotation about the vertical: its tilt and the spread of its yaw about the mean
    measure how far the rotation vector and the mocap disagree (full attitude, no
    body axis involved). The lag is the shift of the phone clock, beyond timeDiff,
    that best matches the gyroscope to the mocap's angular rates (0 if timeDiff and
    its sign are right).
    """
    sel = valid & (t_phone >= base["t"][0] + CONVERGENCE_S) & (t_phone <= base["t"][-1])
    rv = trial["rv"]
    sel &= (t_phone >= rv[0, 0]) & (t_phone <= rv[-1, 0])
    r_rv = quaternions_wxyz_to_matrices(rotation_vector_at(rv, t_phone[sel]))
    d = r_rv @ matrices[sel].transpose(0, 2, 1)
    tilt = np.degrees(np.arccos(np.clip(d[:, 2, 2], -1.0, 1.0)))
    yaw = np.degrees(np.arctan2(d[:, 1, 0] - d[:, 0, 1], d[:, 0, 0] + d[:, 1, 1]))
    yaw_rms, _ = offset_removed_rms(yaw)

    # Body rates of the mocap between successive valid frames, against the gyro.
    pair = valid[:-1] & valid[1:]
    step = np.einsum("nji,njk->nik", matrices[:-1][pair], matrices[1:][pair])
    rate = Rotation.from_matrix(step).as_rotvec() * MOCAP_RATE_HZ
    t_mid = 0.5 * (t_phone[:-1] + t_phone[1:])[pair]
    gyr = trial["gyr"]
    best = (math.inf, 0.0)
    for lag in np.arange(-0.5, 0.5001, 0.005):
        ts = t_mid + lag
        inside = (ts > gyr[0, 0]) & (ts < gyr[-1, 0])
        g = np.column_stack([np.interp(ts[inside], gyr[:, 0], gyr[:, c]) for c in (1, 2, 3)])
        # median: robust to the mocap's glitches
        err = float(np.median(np.sum((g - rate[inside]) ** 2, axis=1)))
        best = min(best, (err, float(lag)))
    return {
        "rv_vs_mocap_yaw_rms_deg": yaw_rms,
        "rv_vs_mocap_tilt_rms_deg": float(np.sqrt(np.mean(tilt**2))),
        "residual_lag_s": best[1],
        "frames": int(sel.sum()),
    }


# ------------------------------------------------------------------------- a trial


def process_trial(folder, name, ours_dir, truth_dir=None):
    trial = load_trial(folder, name)
    mount, body_x, mean_force = detect_mount(trial["acc"])
    t_mocap, matrices = trial["mocap"]
    t_phone = t_mocap - trial["time_diff"]

    valid = ~np.isnan(matrices).any(axis=(1, 2))
    nan_frames = int((~valid).sum())
    flagged = np.zeros_like(valid)
    for start, end in MOCAP_BAD_INTERVALS.get(name, []):
        flagged |= (t_mocap >= start) & (t_mocap <= end)
    flagged_frames = int((flagged & valid).sum())
    valid &= ~flagged
    matrices = np.where(valid[:, None, None], matrices, np.eye(3))

    base = common_base(trial)
    result = {
        "trial": name,
        "disturbed": "_Dist_" in name,
        "mean_specific_force_device": [round(float(v), 3) for v in mean_force],
        "time_diff_s": trial["time_diff"],
        "mocap_frames": len(t_mocap),
        "mocap_nan_frames": nan_frames,
        "mocap_flagged_frames": flagged_frames,
        "samples": len(base["t"]),
        "rate_hz": base["rate_hz"],
        "frame_check": frame_check(trial, base, t_phone, matrices, valid),
    }
    if mount is None:
        result["mount"] = "side"
        result["skipped"] = (
            "phone on its side (mean specific force %.2f, %.2f, %.2f m/s²): no body x" % tuple(mean_force)
        )
        return result, {}
    result["mount"] = mount

    # Scored frames: valid, inside the log after convergence, not in a hole of it.
    inside = (t_phone >= base["t"][0] + CONVERGENCE_S) & (t_phone <= base["t"][-1])
    for gap_start, gap_end in zip(base["gap_starts"], base["gap_ends"]):
        inside &= ~((t_phone > gap_start) & (t_phone < gap_end))
    candidates = valid & inside
    truth_axis = matrices @ body_x
    vertical = np.abs(truth_axis[:, 2]) > math.cos(math.radians(NEAR_VERTICAL_DEG))
    scored = candidates & ~vertical
    t_scored = t_phone[scored]
    truth = heading_deg(truth_axis[scored], "room")
    if truth_dir is not None:
        truth_dir.mkdir(parents=True, exist_ok=True)
        np.savetxt(
            truth_dir / f"{name}.csv",
            np.column_stack([t_scored, truth]),
            fmt="%.4f",
            delimiter=",",
            header="t_s (phone clock),heading_deg (body x, the mocap room's north)",
        )
    result["frames_candidate"] = int(candidates.sum())
    result["frames_near_vertical"] = int((candidates & vertical).sum())
    result["frames_scored"] = int(scored.sum())

    timing = {}
    headings = {}
    rv = trial["rv"]
    r_rv = quaternions_wxyz_to_matrices(rotation_vector_quaternions(rv))
    headings["rotation_vector"] = (rv[:, 0], heading_deg(r_rv @ body_x, "enu"))

    q, seconds = timed(fusion_loop, base)
    timing["fusion"] = seconds
    headings["fusion"] = (base["t"], heading_deg(quaternions_wxyz_to_matrices(q) @ body_x, "nwu"))
    _, ignored = fusion_loop(base, with_states=True)
    result["fusion_accelerometer_ignored_share"] = float(ignored[:, 0].mean())
    result["fusion_magnetometer_ignored_share"] = float(ignored[:, 1].mean())

    q, seconds = timed(madgwick_loop, base)
    timing["madgwick"] = seconds
    result["madgwick_nan_samples"] = int(np.isnan(q).any(axis=1).sum())
    headings["madgwick"] = (base["t"], heading_deg(quaternions_wxyz_to_matrices(q) @ body_x, "nwu"))

    q, seconds = timed(vqf_loop, base)
    timing["vqf"] = seconds
    headings["vqf"] = (base["t"], heading_deg(quaternions_wxyz_to_matrices(q) @ body_x, VQF_FRAME))

    q, seconds = timed(vqf_offline_loop, base)
    timing["vqf_offline"] = seconds
    headings["vqf_offline"] = (base["t"], heading_deg(quaternions_wxyz_to_matrices(q) @ body_x, VQF_FRAME))

    q0 = rotation_vector_at(rv, base["t"][:1])[0]
    q, seconds = timed(gyro_loop, base, q0)
    timing["gyro"] = seconds
    headings["gyro"] = (base["t"], heading_deg(quaternions_wxyz_to_matrices(q) @ body_x, "enu"))

    result["methods"] = {m: score(t_scored, truth, *headings[m]) for m in METHODS}

    if ours_dir is not None:
        path = Path(ours_dir) / f"{name}.csv"
        if path.exists():
            t, yaw, sigma = load_ours(path)
            result["methods"]["ours"] = score(t_scored, truth, t, yaw)
            window = (t >= t_scored.min()) & (t <= t_scored.max()) & np.isfinite(sigma)
            result["methods"]["ours"]["median_yaw_sigma_deg"] = (
                float(np.median(sigma[window])) if window.any() else None
            )
            result["methods"]["ours"].update(sigma_coverage(t_scored, truth, t, yaw, sigma))
        else:
            result["methods"]["ours"] = {"rms_deg": None, "frames": 0, "missing": str(path)}

    rms = {m: result["methods"][m]["rms_deg"] for m in PEERS if result["methods"][m]["rms_deg"] is not None}
    result["best_peer"] = min(rms, key=rms.get) if rms else None
    n = len(base["t"])
    result["timing"] = {m: {"seconds": s, "samples": n, "samples_per_s": n / s} for m, s in timing.items()}
    return result, timing


# -------------------------------------------------------------------------- output


def cell(value, digits=1):
    return "—" if value is None else f"{value:.{digits}f}"


def markdown(results, with_ours):
    methods = METHODS + (["ours"] if with_ours else [])
    head = ["trial", "mount", "disturbed", "scored", "near-vertical excluded"]
    head += [f"{m} RMS (°)" for m in methods] + ["best peer"]
    if with_ours:
        head.append("ours median σ (°)")
        head.append("ours within 1σ / 2σ")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in results:
        row = [r["trial"], r["mount"], "yes" if r["disturbed"] else "no"]
        if "skipped" in r:
            row += ["skipped: " + r["skipped"], ""] + [""] * len(methods) + [""]
            if with_ours:
                row += ["", ""]
        else:
            share = r["frames_near_vertical"] / max(r["frames_candidate"], 1)
            row += [str(r["frames_scored"]), f"{r['frames_near_vertical']} ({100 * share:.1f} %)"]
            for m in methods:
                entry = r["methods"][m]
                text = cell(entry["rms_deg"])
                if m == "ours" and entry.get("frames", 0) not in (0, r["frames_scored"]):
                    text += f" ({entry['frames']} frames)"
                row.append(text)
            row.append(r["best_peer"] or "—")
            if with_ours:
                ours = r["methods"]["ours"]
                row.append(cell(ours.get("median_yaw_sigma_deg")))
                row.append(f"{cell(ours.get('within_1_sigma_pct'), 0)} / {cell(ours.get('within_2_sigma_pct'), 0)} %")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


def markdown_checks(results):
    head = ["trial", "mocap NaN frames", "flagged frames", "RV−mocap yaw RMS (°)", "RV−mocap tilt RMS (°)",
            "residual lag (s)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in results:
        c = r["frame_check"]
        lines.append(
            f"| {r['trial']} | {r['mocap_nan_frames']} | {r['mocap_flagged_frames']} | "
            f"{c['rv_vs_mocap_yaw_rms_deg']:.1f} | {c['rv_vs_mocap_tilt_rms_deg']:.1f} | {c['residual_lag_s']:+.3f} |"
        )
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data_dir", type=Path, nargs="+", help="folders holding the trial folders")
    parser.add_argument("--ours", type=Path, help="folder of <trial>.csv from our filter")
    parser.add_argument("--json", type=Path, help="write all figures here")
    parser.add_argument(
        "--truth-out",
        type=Path,
        help="write each trial's scored truth (t_s, heading of body x) as DIR/<trial>.csv, "
        "for benches/attitude_tune.rs",
    )
    args = parser.parse_args()

    results = []
    totals = {}
    for name in TRIALS:
        folders = [d / name for d in args.data_dir if (d / name).is_dir()]
        if not folders:
            print(f"{name}: in none of {', '.join(map(str, args.data_dir))}, skipped", file=sys.stderr)
            continue
        folder = folders[0]
        result, timing = process_trial(folder, name, args.ours, args.truth_out)
        if "skipped" in result:
            print(f"{name}: skipped, {result['skipped']}", file=sys.stderr)
        for method, seconds in timing.items():
            total = totals.setdefault(method, {"seconds": 0.0, "samples": 0})
            total["seconds"] += seconds
            total["samples"] += result["samples"]
        results.append(result)

    print(f"Heading of body x, RMS error after removing one constant offset per trial and method "
          f"(first {CONVERGENCE_S:g} s skipped, body x within {NEAR_VERTICAL_DEG:g}° of vertical excluded).\n")
    print(markdown(results, args.ours is not None))
    print("\nFrame check (rotation vector against the mocap, full attitude; gyro-vs-mocap residual lag):\n")
    print(markdown_checks(results))
    for total in totals.values():
        total["samples_per_s"] = total["samples"] / total["seconds"]
    print("\nProcessing time (all scored trials): " + ", ".join(
        f"{m} {t['seconds']:.2f} s ({t['samples_per_s']:.0f} samples/s)" for m, t in totals.items()))

    if args.json:
        report = {
            "benchmark": "tyrex-attitude heading of body x",
            "settings": {
                "convergence_s": CONVERGENCE_S,
                "near_vertical_deg": NEAR_VERTICAL_DEG,
                "max_gap_s": MAX_GAP_S,
                "mocap_bad_intervals": MOCAP_BAD_INTERVALS,
                "imufusion": getattr(imufusion, "__version__", "1.3.3"),
            },
            "trials": results,
            "timing": totals,
        }
        args.json.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
