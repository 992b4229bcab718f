"""The IPIN 2023 Track 3 walks scored as the competition scores them, beside the raw
GNSS and a GNSS-only smoother (issue 42).

For every GetSensorData walk given (default: ../shared/data/ipin2023-track3-walks):

- runs `compass-pdr pdr WALK --out track.csv` (and again with `--outage` over the
  middle 40 % of the walk, first to last landmark);
- the track's horizontal error at each `POSI` landmark (the track's latitude/longitude
  interpolated at the landmark's time), and whether 1 and 2 x its `position_sigma_m`
  cover it;
- the raw GNSS's error (the last fix at or before the landmark, whatever its reported
  accuracy);
- a GNSS-only baseline: filterpy's constant-velocity Kalman filter and RTS smoother on
  the same fixes, each weighted by its reported accuracy (R = accuracy^2 per axis),
  evaluated at the landmark's time;
- the walked distance between the first and last landmark, against the landmarks'
  polyline;
- in the outage run, each landmark inside the outage: error / true distance walked
  since the outage began (along the landmarks' polyline), and the drift: the error of
  the track's displacement since the outage began against the truth's, over the same
  distance (the error the track already had when the GNSS went is not the bridge's);
  and both again for the track with every fix at the same landmarks, the floor no
  bridge of the outage can go below.

Prints per walk, per route and pooled figures; --json writes them all.

    target/bench-venv/bin/python bench/ipin.py [--cli target/release/compass-pdr]
        [--args "ARGS for compass-pdr pdr"] [--json out.json] [WALK...]
"""
import argparse
import json
import math
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_DIR = ROOT.parent / "shared" / "data" / "ipin2023-track3-walks"
EARTH_R_M = 6_371_000.0


def read_walk(path):
    """GNSS fixes (t, lat, lon, accuracy) and POSI landmarks (t, lat, lon) on the app clock."""
    fixes, landmarks = [], []
    with open(path, encoding="utf-8", errors="replace") as lines:
        for line in lines:
            if line.startswith("GNSS;"):
                f = line.strip().split(";")
                fixes.append((float(f[1]), float(f[3]), float(f[4]), float(f[7])))
            elif line.startswith("POSI;"):
                f = line.strip().split(";")
                lat, lon = float(f[3]), float(f[4])
                if lat != 0.0 or lon != 0.0:
                    landmarks.append((float(f[1]), lat, lon))
    return fixes, landmarks


class Frame:
    """East/north metres about an origin (equirectangular: walks of 100 m)."""

    def __init__(self, lat0, lon0):
        self.lat0, self.lon0 = lat0, lon0
        self.k = math.cos(math.radians(lat0))

    def en(self, lat, lon):
        return (
            math.radians(lon - self.lon0) * EARTH_R_M * self.k,
            math.radians(lat - self.lat0) * EARTH_R_M,
        )


def read_track(path):
    rows = []
    with open(path) as lines:
        header = lines.readline().strip().split(",")
        idx = {name: i for i, name in enumerate(header)}
        for line in lines:
            f = line.strip().split(",")
            if len(f) < len(header):
                continue
            lat = f[idx["lat_deg"]] if "lat_deg" in idx else ""
            lon = f[idx["lon_deg"]] if "lon_deg" in idx else ""
            rows.append(
                (
                    float(f[idx["t_s"]]),
                    float(lat) if lat not in ("", "nan") else math.nan,
                    float(lon) if lon not in ("", "nan") else math.nan,
                    float(f[idx["position_sigma_m"]]),
                    float(f[idx["east_m"]]),
                    float(f[idx["north_m"]]),
                )
            )
    return rows


def interp(ts, values, t):
    """Linear interpolation, clamped at the ends."""
    if t <= ts[0]:
        return values[0]
    if t >= ts[-1]:
        return values[-1]
    i = int(np.searchsorted(ts, t))
    w = (t - ts[i - 1]) / (ts[i] - ts[i - 1]) if ts[i] > ts[i - 1] else 0.0
    return values[i - 1] + w * (values[i] - values[i - 1])


def gnss_smoother(fixes, frame, q=0.5):
    """filterpy's CV Kalman filter + RTS smoother over the fixes (one per distinct fix
    time), R = accuracy^2 per axis, white-noise acceleration q (m/s^2)^2/Hz per axis."""
    seen, rows = set(), []
    for t, lat, lon, acc in fixes:
        key = (lat, lon, acc)
        if key in seen and rows and t - rows[-1][0] < 1.5:
            continue
        seen.add(key)
        e, n = frame.en(lat, lon)
        rows.append((t, e, n, max(acc, 1.0)))
    if not rows:
        return None
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.x = np.array([rows[0][1], 0.0, rows[0][2], 0.0])
    kf.P = np.diag([rows[0][3] ** 2, 4.0, rows[0][3] ** 2, 4.0])
    kf.H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    xs, ps, fs, qs = [], [], [], []
    last_t = rows[0][0]
    for t, e, n, acc in rows:
        dt = max(t - last_t, 1e-3)
        last_t = t
        f1 = np.array([[1.0, dt], [0, 1.0]])
        kf.F = np.block([[f1, np.zeros((2, 2))], [np.zeros((2, 2)), f1]])
        q1 = Q_discrete_white_noise(dim=2, dt=dt, var=q)
        kf.Q = np.block([[q1, np.zeros((2, 2))], [np.zeros((2, 2)), q1]])
        kf.predict()
        kf.R = np.eye(2) * acc**2
        kf.update(np.array([e, n]))
        xs.append(kf.x.copy())
        ps.append(kf.P.copy())
        fs.append(kf.F.copy())
        qs.append(kf.Q.copy())
    # filterpy's rts_smoother takes F and Q of the step into k+1 at index k+1.
    xs_s, _, _, _ = kf.rts_smoother(np.array(xs), np.array(ps), Fs=np.array(fs), Qs=np.array(qs))
    ts = np.array([r[0] for r in rows])
    return ts, xs_s[:, 0], xs_s[:, 2]


def polyline_length(points):
    return sum(math.dist(a, b) for a, b in zip(points, points[1:]))


def run_cli(cli, walk, outage, out, extra):
    args = [str(cli), "pdr", str(walk), "--out", str(out)] + extra
    if outage:
        args += ["--outage", f"{outage[0]:.3f}:{outage[1]:.3f}"]
    done = subprocess.run(args, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{walk.name}: compass-pdr exited {done.returncode}: {done.stderr[-400:]}")


def score_walk(cli, walk, tmp, extra):
    fixes, landmarks = read_walk(walk)
    frame = Frame(landmarks[0][1], landmarks[0][2])
    truth = [(t, *frame.en(lat, lon)) for t, lat, lon in landmarks]
    t_first, t_last = truth[0][0], truth[-1][0]
    span = t_last - t_first
    outage = (t_first + 0.3 * span, t_first + 0.7 * span)
    result = {"walk": walk.name, "route": walk.name.split("Trial")[1][:2], "landmarks": len(truth)}

    # Raw GNSS: the last fix at or before the landmark.
    raw = []
    for t, e, n in truth:
        before = [f for f in fixes if f[0] <= t]
        fix = before[-1] if before else (fixes[0] if fixes else None)
        raw.append(math.dist(frame.en(fix[1], fix[2]), (e, n)) if fix else math.nan)
    result["raw_gnss_m"] = raw
    smooth = gnss_smoother(fixes, frame)
    result["gnss_smoother_m"] = (
        [
            math.dist((interp(smooth[0], smooth[1], t), interp(smooth[0], smooth[2], t)), (e, n))
            for t, e, n in truth
        ]
        if smooth
        else [math.nan] * len(truth)
    )

    tracks = {}
    for name, cut in (("track", None), ("outage", outage)):
        out = Path(tmp) / f"{walk.stem}-{name}.csv"
        run_cli(cli, walk, cut, out, extra)
        rows = read_track(out)
        tracks[name] = rows
        ts = np.array([r[0] for r in rows])
        geo = not any(math.isnan(r[1]) for r in rows)
        errors, sigmas = [], []
        for t, e, n in truth:
            sigma = interp(ts, np.array([r[3] for r in rows]), t)
            if geo:
                lat = interp(ts, np.array([r[1] for r in rows]), t)
                lon = interp(ts, np.array([r[2] for r in rows]), t)
                errors.append(math.dist(frame.en(lat, lon), (e, n)))
            else:
                errors.append(math.nan)
            sigmas.append(sigma)
        result[f"{name}_m"] = errors
        result[f"{name}_sigma_m"] = sigmas
        result[f"{name}_geo"] = geo
        if name == "track":
            # Walked distance between the first and the last landmark.
            en = [(interp(ts, np.array([r[4] for r in rows]), t), interp(ts, np.array([r[5] for r in rows]), t)) for t in ts if t_first <= t <= t_last]
            walked = polyline_length(en)
            result["walked_m"] = walked
            result["truth_m"] = polyline_length([(e, n) for _, e, n in truth])
    # Landmarks inside the outage: error / distance walked since it began, for the
    # track with the outage and, as the floor no bridge can go below, the track with
    # every fix at the same landmarks.
    for name in ("outage", "track"):
        ratios, drifts, walked_since = outage_scores(truth, outage, tracks[name], result[f"{name}_m"])
        result[f"{name}_outage_pct" if name == "track" else "outage_pct"] = ratios
        result[f"{name}_outage_drift_pct" if name == "track" else "outage_drift_pct"] = drifts
        result["outage_walked_m"] = walked_since
    return result


def outage_scores(truth, outage, rows, errors):
    """Each landmark inside the outage: its error, and the drift (the error of the track's
    displacement since the outage began against the truth's), both in % of the distance
    walked since the outage began along the landmarks' polyline."""
    ts = np.array([r[0] for r in rows])
    start = (
        interp(np.array([p[0] for p in truth]), np.array([p[1] for p in truth]), outage[0]),
        interp(np.array([p[0] for p in truth]), np.array([p[2] for p in truth]), outage[0]),
    )
    track_e = np.array([r[4] for r in rows])
    track_n = np.array([r[5] for r in rows])
    track_start = (interp(ts, track_e, outage[0]), interp(ts, track_n, outage[0]))
    ratios, drifts, walked_since = [], [], []
    for i, (t, e, n) in enumerate(truth):
        if not (outage[0] < t <= outage[1]):
            continue
        path = [start] + [(p[1], p[2]) for p in truth[: i + 1] if p[0] > outage[0]]
        walked = polyline_length(path)
        if walked > 1.0 and not math.isnan(errors[i]):
            ratios.append(100.0 * errors[i] / walked)
            moved = (interp(ts, track_e, t) - track_start[0], interp(ts, track_n, t) - track_start[1])
            drifts.append(100.0 * math.dist(moved, (e - start[0], n - start[1])) / walked)
            walked_since.append(walked)
    return ratios, drifts, walked_since


def p75(values):
    values = [v for v in values if not math.isnan(v)]
    return float(np.percentile(values, 75)) if values else math.nan


def median(values):
    values = [v for v in values if not math.isnan(v)]
    return statistics.median(values) if values else math.nan


def coverage(errors, sigmas, k):
    pairs = [(e, s) for e, s in zip(errors, sigmas) if not math.isnan(e)]
    return 100.0 * sum(e <= k * s for e, s in pairs) / len(pairs) if pairs else math.nan


def summary(label, results):
    track = [e for r in results for e in r["track_m"]]
    sig = [s for r in results for s in r["track_sigma_m"]]
    raw = [e for r in results for e in r["raw_gnss_m"]]
    smooth = [e for r in results for e in r["gnss_smoother_m"]]
    outage = [x for r in results for x in r["outage_pct"]]
    drift = [x for r in results for x in r["outage_drift_pct"]]
    floor = [x for r in results for x in r["track_outage_pct"]]
    floor_drift = [x for r in results for x in r["track_outage_drift_pct"]]
    nan = sum(math.isnan(e) for e in track)
    print(
        f"{label:<10} P75 track {p75(track):5.1f} m  raw GNSS {p75(raw):5.1f}  GNSS smoother "
        f"{p75(smooth):5.1f}  | median {median(track):4.1f} / {median(raw):4.1f} / {median(smooth):4.1f}"
        f"  | 1σ {coverage(track, sig, 1):3.0f} %  2σ {coverage(track, sig, 2):3.0f} %"
        f"  | outage: median error {median(outage):4.1f} %, drift {median(drift):4.1f} % of the distance ({len(outage)} landmarks); with every fix {median(floor):4.1f} / {median(floor_drift):4.1f} %"
        + (f"  | {nan} landmarks without lat/lon" if nan else "")
    )


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--cli", default=str(ROOT / "target" / "release" / "compass-pdr"))
    parser.add_argument("--json")
    parser.add_argument("--args", default="", help="more arguments for compass-pdr pdr")
    parser.add_argument("walks", nargs="*")
    args = parser.parse_args()
    walks = [Path(w) for w in args.walks] or sorted(DEFAULT_DIR.glob("*.txt"))
    if not walks:
        sys.exit(f"no walks in {DEFAULT_DIR}")
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for walk in walks:
            extra = args.args.split()
            r = score_walk(Path(args.cli), walk, tmp, extra)
            results.append(r)
            ratio = r["walked_m"] / r["truth_m"] - 1.0
            print(
                f"{r['walk']:<42} median {median(r['track_m']):5.1f} m (raw {median(r['raw_gnss_m']):5.1f}, "
                f"smoother {median(r['gnss_smoother_m']):5.1f})  P75 {p75(r['track_m']):5.1f}  "
                f"2σ {coverage(r['track_m'], r['track_sigma_m'], 2):3.0f} %  "
                f"distance {100 * ratio:+4.0f} %  outage {median(r['outage_pct']):4.1f} %"
                + ("" if r["track_geo"] else "  NO LAT/LON")
            )
    for route in sorted({r["route"] for r in results}):
        summary(f"route {route}", [r for r in results if r["route"] == route])
    summary("pooled", results)
    ratios = [r["walked_m"] / r["truth_m"] - 1.0 for r in results]
    print(
        f"distance: {sum(abs(x) <= 0.10 for x in ratios)} of {len(ratios)} walks within ±10 %, "
        f"median {100 * statistics.median(ratios):+.1f} %"
    )
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
