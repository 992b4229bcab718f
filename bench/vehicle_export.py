#!/usr/bin/env python3
"""The shared car drive's exported device calibration applied as its JSON text says
(issue 43: within 1.2 × the tool's best calibration heading), independently of the
tool's own levelling: `compass-pdr calibrate LOG --json`'s `device_calibration.sensor`
(corrected = soft_iron · (raw − hard_iron), Android device axes) on the log's raw
magnetometer columns, turned into body axes as the log's mount says (upright: body
x = −device z, y = device x, z = −device y), levelled with the phone's own gravity
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

import numpy as np

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

    def body(v):
        return np.array([-v[2], v[0], -v[1]])

    t0, samples = None, []
    for row in csv.DictReader(open(args.log, newline="")):
        t = datetime.datetime.fromisoformat(row["time"]).timestamp()
        t0 = t if t0 is None else t0
        try:
            raw = np.array([float(row[f"mag_{a}"]) for a in "xyz"])
            gravity = np.array([float(row[f"grav_{a}"]) for a in "xyz"])
            speed, bearing, accuracy = (float(row[k]) for k in ("speed", "bearing", "horizontalAccuracy"))
        except ValueError:
            continue
        field, down = body(soft_iron @ (raw - hard_iron)), -body(gravity)
        down /= np.linalg.norm(down)
        north = field - (field @ down) * down
        north /= np.linalg.norm(north)
        east = np.cross(down, north)
        heading = math.degrees(math.atan2(east[0], north[0])) + declination_deg
        samples.append((t - t0, heading, speed, bearing, accuracy))
    s = np.array(samples)
    print(f"{args.log}: the export of the {report['device_calibration']['method']} method, applied as written")
    for name, keep in (("whole log", s[:, 0] >= 0), (f"check part (t ≥ {split_s} s)", s[:, 0] >= split_s)):
        keep &= (s[:, 2] >= 5.0) & (s[:, 4] <= 15.0)
        error = (s[keep, 1] - s[keep, 3] + 180.0) % 360.0 - 180.0
        print(f"  {name}: {keep.sum()} fixes, mean {error.mean():+.2f}°, RMS {math.sqrt((error ** 2).mean()):.2f}°")
    print("  the tool's own check RMS per calibration:", ", ".join(
        f"{m['method']} {m['heading_error_check']['rms_deg']:.2f}°" for m in report["methods"]
        if m.get("heading_error_check")))

if __name__ == "__main__":
    main()
