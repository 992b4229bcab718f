#!/usr/bin/env python3
"""The peers of compass-pdr's autopilot-log import, on the same files.

pymavlink (DataFlash .bin and .log): `mavutil.mavlink_connection(path)`, then every
message with `recv_msg()` until the end, as `mavlogdump.py` reads a log; and the same
with `recv_match(type=[...])` for the messages compass-pdr uses.
pyulog (ULog): `ULog(path)`, every topic; and with `message_name_filter_list` set to
the topics compass-pdr uses.

Each is timed several times (wall clock, the file in the page cache); medians are
printed as one JSON object per line. Usage: autopilot_peer.py FILE... [--runs N] [--only-all]
"""

import argparse
import json
import os
import statistics
import time

USED_DATAFLASH = ["FMT", "PARM", "MSG", "MAG", "MAG2", "MAG3", "IMU", "GPS", "ATT", "CURR", "BAT"]
USED_ULOG = ["sensor_combined", "sensor_mag", "vehicle_magnetometer", "vehicle_attitude",
             "vehicle_gps_position", "sensor_gps"]


def dataflash_all(path):
    from pymavlink import mavutil
    log = mavutil.mavlink_connection(path)
    n = 0
    while log.recv_msg() is not None:
        n += 1
    return n


def dataflash_used(path):
    from pymavlink import mavutil
    log = mavutil.mavlink_connection(path)
    n = 0
    while log.recv_match(type=USED_DATAFLASH) is not None:
        n += 1
    return n


def ulog_all(path):
    from pyulog import ULog
    return sum(len(d.data["timestamp"]) for d in ULog(path).data_list)


def ulog_used(path):
    from pyulog import ULog
    return sum(len(d.data["timestamp"]) for d in ULog(path, USED_ULOG).data_list)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("files", nargs="+")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--only-all", action="store_true", help="only the reading of every message")
    args = parser.parse_args()
    for path in args.files:
        if path.endswith(".ulg"):
            peers = [("pyulog ULog(path)", ulog_all), ("pyulog, the topics used", ulog_used)]
        else:
            peers = [("pymavlink recv_msg (mavlogdump)", dataflash_all),
                     ("pymavlink recv_match, the messages used", dataflash_used)]
        if args.only_all:
            peers = peers[:1]
        for name, work in peers:
            seconds = []
            count = 0
            for _ in range(args.runs):
                start = time.perf_counter()
                count = work(path)
                seconds.append(time.perf_counter() - start)
            print(json.dumps({"file": os.path.basename(path), "peer": name, "bytes": os.path.getsize(path),
                              "median_s": statistics.median(seconds), "runs": args.runs, "count": count}),
                  flush=True)


if __name__ == "__main__":
    main()
