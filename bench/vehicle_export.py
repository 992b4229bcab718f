#!/usr/bin/env python3
"""The shared car drive's exported device calibration applied as its JSON text says
(issue 43: within 1.2 × the tool's best calibration heading), independently of the
tool's own levelling: `compass-pdr calibrate LOG --json`'s `device_calibration.sensor`
(corrected = soft_iron · (raw − hard_iron), Android device axes) on the log's raw
magnetometer columns, turned into body axes by the mount the mean gravity gives (the
rule of src/io/axes.rs, attitude_peers.detect_mount and body_from_device), levelled with the phone's own gravity
sensor (`grav_*`, not the tool's down), the WMM declination the tool printed added, and
set against the GPS bearing at 5 m/s or faster with a horizontal accuracy within 15 m.

Usage:
    vehicle_export.py [--cli target/release/compass-pdr] [LOG]
"""

import argparse
import csv
import datetime
import json
import math
import subprocess

import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import attitude_peers as peers  # noqa: E402

DEFAULT_LOG = "../shared/data/vehicle-pixel6a/2023-08-09_12-47-42.csv"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("log", nargs="?", default=DEFAULT_LOG)
    parser.add_argument("--cli", default="target/release/compass-pdr")
    args = parser.parse_args()
    report = json.loads(subprocess.run([args.cli, "calibrate", args.log, "--json"], check=True,
                                       capture_output=True, text=True).stdout)
    export = report["device_calibration"]["sensor"]
    hard_iron, soft_iron = np.array(export["hard_iron"]), np.array(export["soft_iron"])
    declination_deg = report["declination"]["declination_deg"]
    split_s = report["train_until_s"]

    rows = []
    t0 = None
    for row in csv.DictReader(open(args.log, newline="")):
        t = datetime.datetime.fromisoformat(row["time"]).timestamp()
        t0 = t if t0 is None else t0
        try:
            raw = [float(row[f"mag_{a}"]) for a in "xyz"]
            gravity = [float(row[f"grav_{a}"]) for a in "xyz"]
            fix = [float(row[k]) for k in ("speed", "bearing", "horizontalAccuracy")]
        except ValueError:
            continue
        rows.append([t - t0, *raw, *gravity, *fix])
    table = np.array(rows)
    mount, _, _ = peers.detect_mount(table[:, [0, 4, 5, 6]])
    samples = []
    for t, *values in table:
        raw, gravity, (speed, bearing, accuracy) = np.array(values[0:3]), np.array(values[3:6]), values[6:9]
        field = peers.body_from_device(mount, soft_iron @ (raw - hard_iron))
        down = -peers.body_from_device(mount, gravity)
        down /= np.linalg.norm(down)
        north = field - (field @ down) * down
        north /= np.linalg.norm(north)
        east = np.cross(down, north)
        heading = math.degrees(math.atan2(east[0], north[0])) + declination_deg
        samples.append((t, heading, speed, bearing, accuracy))
    s = np.array(samples)
    print(f"{args.log} ({mount}): the export of the {report['device_calibration']['method']} method, applied as written")
    for name, keep in (("whole log", s[:, 0] >= 0), (f"check part (t ≥ {split_s} s)", s[:, 0] >= split_s)):
        keep &= (s[:, 2] >= 5.0) & (s[:, 4] <= 15.0)
        error = (s[keep, 1] - s[keep, 3] + 180.0) % 360.0 - 180.0
        print(f"  {name}: {keep.sum()} fixes, mean {error.mean():+.2f}°, RMS {math.sqrt((error ** 2).mean()):.2f}°")
    print("  the tool's own check RMS per calibration:", ", ".join(
        f"{m['method']} {m['heading_error_check']['rms_deg']:.2f}°" for m in report["methods"]
        if m.get("heading_error_check")))

if __name__ == "__main__":
    main()
