"""Writes the simulated walk `walk.csv` (the canonical CSV of `compass-pdr simulate`) in
two phone apps' formats, for the golden cases of their importers (tests/data/cases.txt):

- `getsensordata-walk.txt`: a GetSensorData log (the IPIN competitions' Android app),
  as its own header and `String.format` calls write it (GitHub
  lopsi/GetSensorData_Android, MainActivity.java; the fields are listed in
  src/io/tagged_lines/get_sensor_data.rs): `ACCE`, `GYRO`, `MAGN` lines on the app's
  clock (seconds since logging started) and the sensor's (here the same plus 9635 s),
  `GNSS` lines with the fix's time in seconds since 1970, and three `POSI` landmarks
  placed where the walk's truth was at those times;
- `sensorlogger-walk/`: Sensor Logger's per-sensor CSV export (the Android app's:
  `time` in ns since 1970, `seconds_elapsed`, vectors as `z,y,x`):
  `TotalAcceleration.csv`, `Gyroscope.csv`, `MagnetometerUncalibrated.csv`,
  `Location.csv` and `Metadata.csv`;
- `walk.ulg`: a PX4 ULog (docs.px4.io, "ULog File Format"; pyulog's `core.py` reads
  it): the 16-byte header, flag bits, the formats of `sensor_combined`, `sensor_mag`
  (gauss, as PX4 logs it) and `vehicle_gps_position` (degrees × 10⁷, as PX4 logs
  them), the system's name, the parameters a compass calibration of zero leaves in
  force (`CAL_MAG0_*`), then the subscriptions and one data message per sample, times
  in µs since boot. A multicopter's body axes are x forward, y right, z down, walk.csv's
  own, so the vectors are written as they are;
- `indoor-walk.txt`: an Android sensor dump as the Microsoft Indoor Location Competition
  2020's logger writes it (src/io/tagged_lines/android.rs): its `#` headers, then one
  line per event, `unix_ms<TAB>TYPE_…<TAB>values`, the seven motion sensors of each
  sample (the OS's calibrated and uncalibrated accelerometer, gyroscope and field, and
  the rotation vector), a `TYPE_WIFI` scan each second and a `TYPE_WAYPOINT` every 3 s
  (the walk's truth in metres, east and north);
- `tyrex-walk/`: the TYREX attitude benchmark's per-sensor text files
  (src/io/sensor_files/headerless.rs): `accelerometer.txt`, `gyroscope.txt` and
  `magnetometer.txt` with the OS's drift and bias estimates, their calibrated copies,
  and `record.properties` with the start time.

The last two are the analysis worker's warm-up logs of those formats too
(scripts/setup.sh, `WARM_UP_LOGS`), beside the others.

The field is written as the simulator made it, hard iron included, in both (GetSensorData's
`MAGN` is the OS-calibrated field on a real phone; the importer says so and the fits find the
simulated offset all the same).

walk.csv holds body axes (x forward, y right, z down) of a phone held flat, screen up,
its top forward: Android's device axes (x right, y towards the top, z out of the screen)
are then (body y, body x, −body z), for the specific force, the rate and the field alike.

    python3 tests/data/formats.py     # from the repository's root; no package needed
"""

import csv
import math
import struct
from pathlib import Path

HERE = Path(__file__).resolve().parent
EARTH_R_M = 6_371_000.0
SENSOR_CLOCK_OFFSET_S = 9635.0


def device(x, y, z):
    """Body (x forward, y right, z down) to Android device axes, phone flat screen up."""
    return (y, x, -z)


def rows():
    with open(HERE / "walk.csv", newline="") as lines:
        yield from csv.DictReader(lines)


def vector(row, prefix, unit):
    return device(*(float(row[f"{prefix}_{axis}_{unit}"]) for axis in "xyz"))


def main():
    data = list(rows())
    t0 = float(data[0]["t_s"])
    lat0, lon0 = float(data[0]["lat_deg"]), float(data[0]["lon_deg"])

    def lat_lon(east_m, north_m):
        lat = lat0 + math.degrees(north_m / EARTH_R_M)
        lon = lon0 + math.degrees(east_m / (EARTH_R_M * math.cos(math.radians(lat0))))
        return lat, lon

    # GetSensorData: one text file.
    lines = [
        "% LogFile created by the 'GetSensorData' App for Android.",
        "% Written by tests/data/formats.py from walk.csv (a simulated walk).",
    ]
    landmarks = {0, len(data) // 2, len(data) - 1}
    for idx, row in enumerate(data):
        app_s = float(row["t_s"]) - t0
        sensor_s = app_s + SENSOR_CLOCK_OFFSET_S
        for tag, prefix, unit in (("ACCE", "acc", "mps2"), ("GYRO", "gyro", "radps"), ("MAGN", "mag", "ut")):
            x, y, z = vector(row, prefix, unit)
            lines.append(f"{tag};{app_s:.3f};{sensor_s:.3f};{x:.5f};{y:.5f};{z:.5f};3")
        if row["lat_deg"]:
            lines.append(
                f"GNSS;{app_s:.3f};{float(row['t_s']):.3f};{float(row['lat_deg']):.7f};{float(row['lon_deg']):.7f};"
                f"12.000;{float(row['gps_course_deg']):.3f};{float(row['gps_hacc_m']):.1f};"
                f"{max(float(row['gps_speed_mps']), 0.0):.2f};12;9"
            )
        if idx in landmarks:
            lat, lon = lat_lon(float(row["ref_e_m"]), float(row["ref_n_m"]))
            lines.append(f"POSI;{app_s:.3f};{len([i for i in landmarks if i <= idx])};{lat:.8f};{lon:.8f};0;1")
    (HERE / "getsensordata-walk.txt").write_text("\n".join(lines) + "\n")

    # Sensor Logger: one CSV per sensor.
    folder = HERE / "sensorlogger-walk"
    folder.mkdir(exist_ok=True)
    for name, prefix, unit in (
        ("TotalAcceleration", "acc", "mps2"),
        ("Gyroscope", "gyro", "radps"),
        ("MagnetometerUncalibrated", "mag", "ut"),
    ):
        out = ["time,seconds_elapsed,z,y,x"]
        for row in data:
            x, y, z = vector(row, prefix, unit)
            t = float(row["t_s"])
            out.append(f"{round(t * 1e9)},{t - t0:.6f},{z:.6f},{y:.6f},{x:.6f}")
        (folder / f"{name}.csv").write_text("\n".join(out) + "\n")
    out = ["time,seconds_elapsed,horizontalAccuracy,speed,bearing,altitude,longitude,latitude"]
    for row in data:
        if row["lat_deg"]:
            t = float(row["t_s"])
            out.append(
                f"{round(t * 1e9)},{t - t0:.3f},{float(row['gps_hacc_m']):.1f},{max(float(row['gps_speed_mps']), 0.0):.2f},"
                f"{float(row['gps_course_deg']):.2f},12.0,{float(row['lon_deg']):.7f},{float(row['lat_deg']):.7f}"
            )
    (folder / "Location.csv").write_text("\n".join(out) + "\n")
    write_ulog(data, t0)
    write_indoor_dump(data)
    write_tyrex(data, t0)
    (folder / "Metadata.csv").write_text(
        "version,device name,recording time,platform,appVersion,device id,sensors,sampleRateMs\n"
        "3,simulated,2026-05-14_16-30-00,android,1.12.0,formats.py,"
        "TotalAcceleration|Gyroscope|MagnetometerUncalibrated|Location,20|20|20|0\n"
    )


class Ulog:
    """A ULog written message by message: u16 size (LE), u8 type, payload."""

    def __init__(self, start_us):
        self.bytes = bytearray(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", start_us))

    def message(self, kind, payload):
        self.bytes += struct.pack("<HB", len(payload), ord(kind)) + payload

    def key_value(self, kind, key, value):
        self.message(kind, bytes([len(key)]) + key.encode() + value)


MAG_DEVICE_ID = 396_809  # an I2C compass's id, as PX4 composes them
UT_PER_GAUSS = 100.0


def write_ulog(data, t0):
    log = Ulog(0)
    log.message("B", bytes(40))  # flag bits: no compat/incompat flags, no appended data
    log.message(
        "F",
        b"sensor_combined:uint64_t timestamp;float[3] gyro_rad;uint32_t gyro_integral_dt;"
        b"int32_t accelerometer_timestamp_relative;float[3] accelerometer_m_s2;"
        b"uint32_t accelerometer_integral_dt;uint8_t accelerometer_clipping;uint8_t[3] _padding0;",
    )
    log.message(
        "F",
        b"sensor_mag:uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;float x;"
        b"float y;float z;float temperature;uint32_t error_count;bool is_external;uint8_t[7] _padding0;",
    )
    log.message(
        "F",
        b"vehicle_gps_position:uint64_t timestamp;uint64_t time_utc_usec;int32_t lat;int32_t lon;"
        b"int32_t alt;float eph;float epv;float vel_m_s;float cog_rad;uint8_t fix_type;uint8_t[7] _padding0;",
    )
    log.key_value("I", "char[3] sys_name", b"PX4")
    log.key_value("I", "char[6] ver_sw_release", b"v1.14\x00"[:6])
    log.key_value("P", "int32_t CAL_MAG0_ID", struct.pack("<i", MAG_DEVICE_ID))
    log.key_value("P", "int32_t CAL_MAG0_ROT", struct.pack("<i", 0))
    for axis in "XYZ":
        log.key_value("P", f"float CAL_MAG0_{axis}OFF", struct.pack("<f", 0.0))
        log.key_value("P", f"float CAL_MAG0_{axis}SCALE", struct.pack("<f", 1.0))
    for msg_id, name in ((0, "sensor_combined"), (1, "sensor_mag"), (2, "vehicle_gps_position")):
        log.message("A", bytes([0]) + struct.pack("<H", msg_id) + name.encode())
    for row in data:
        t = float(row["t_s"])
        t_us = 1_000_000 + round((t - t0) * 1e6)
        gyro = [float(row[f"gyro_{a}_radps"]) for a in "xyz"]
        acc = [float(row[f"acc_{a}_mps2"]) for a in "xyz"]
        log.message("D", struct.pack("<HQ3fIi3fIB3x", 0, t_us, *gyro, 20_000, 0, *acc, 20_000, 0))
        mag = [float(row[f"mag_{a}_ut"]) / UT_PER_GAUSS for a in "xyz"]
        temp = float(row["temp_c"]) if row["temp_c"] else 20.0
        log.message("D", struct.pack("<HQQI3ffI?7x", 1, t_us, t_us, MAG_DEVICE_ID, *mag, temp, 0, False))
        if row["lat_deg"]:
            log.message(
                "D",
                struct.pack(
                    "<HQQiiiffffB7x",
                    2,
                    t_us,
                    round(t * 1e6),
                    round(float(row["lat_deg"]) * 1e7),
                    round(float(row["lon_deg"]) * 1e7),
                    12_000,
                    float(row["gps_hacc_m"]),
                    2 * float(row["gps_hacc_m"]),
                    max(float(row["gps_speed_mps"]), 0.0),
                    math.radians(float(row["gps_course_deg"])),
                    3,
                ),
            )
    (HERE / "walk.ulg").write_bytes(bytes(log.bytes))


# The OS's estimates the phone apps write beside the raw readings, in device axes: the
# field's hard-iron bias (µT) and the gyroscope's drift (rad/s).
OS_MAG_BIAS_UT = (12.5, -7.25, 30.0)
OS_GYRO_DRIFT_RADPS = (0.002, -0.001, 0.0005)


def rotation_vector(heading_deg):
    """Android's rotation vector (x, y, z, device to east-north-up) of a phone held flat,
    screen up, its top towards `heading_deg` (clockwise from north): a turn of
    −heading about up."""
    half = math.radians(-heading_deg) / 2
    return (0.0, 0.0, math.sin(half))


def tabbed(values):
    """Values as the Microsoft logger writes them: tab-separated."""
    return "\t".join(f"{v:.6f}" for v in values)


def spaced(values):
    """Values as TYREX's logger writes them: space-separated, up to 7 digits."""
    return " ".join(f"{v:.7g}" for v in values)


def write_indoor_dump(data):
    start_ms = round(float(data[0]["t_s"]) * 1000)
    lines = [
        f"#\tstartTime:{start_ms}",
        "#\tSiteID:simulated\tSiteName:formats.py\tFloorId:simulated-F1\tFloorName:F1",
        "#\tBrand:simulated\tModel:formats.py\tAndroidName:8.1.0\tAPILevel:27\t",
        "#\ttype:1\tname:Accelerometer\tversion:1\tvendor:simulated\tresolution:0.0024\tpower:0.18\tmaximumRange:39.2",
        "#\ttype:4\tname:Gyroscope\tversion:1\tvendor:simulated\tresolution:0.0011\tpower:0.9\tmaximumRange:34.9",
        "#\ttype:2\tname:Magnetometer\tversion:1\tvendor:simulated\tresolution:0.6\tpower:2.4\tmaximumRange:4912.0",
    ]
    last_wifi_ms = None
    for idx, row in enumerate(data):
        t_ms = round(float(row["t_s"]) * 1000)
        acc = vector(row, "acc", "mps2")
        gyro = vector(row, "gyro", "radps")
        mag = vector(row, "mag", "ut")
        calibrated = [m - b for m, b in zip(mag, OS_MAG_BIAS_UT)]
        raw_gyro = [g + d for g, d in zip(gyro, OS_GYRO_DRIFT_RADPS)]
        heading = float(row["ref_heading_deg"])
        lines += [
            f"{t_ms}\tTYPE_ACCELEROMETER\t{tabbed(acc)}\t3",
            f"{t_ms}\tTYPE_MAGNETIC_FIELD\t{tabbed(calibrated)}\t3",
            f"{t_ms}\tTYPE_GYROSCOPE\t{tabbed(gyro)}\t3",
            f"{t_ms}\tTYPE_ROTATION_VECTOR\t{tabbed(rotation_vector(heading))}\t3",
            f"{t_ms}\tTYPE_MAGNETIC_FIELD_UNCALIBRATED\t{tabbed(mag)}\t{tabbed(OS_MAG_BIAS_UT)}\t3",
            f"{t_ms}\tTYPE_GYROSCOPE_UNCALIBRATED\t{tabbed(raw_gyro)}\t{tabbed(OS_GYRO_DRIFT_RADPS)}\t3",
            f"{t_ms}\tTYPE_ACCELEROMETER_UNCALIBRATED\t{tabbed(acc)}\t0.000000\t0.000000\t0.000000\t3",
        ]
        if last_wifi_ms is None or t_ms - last_wifi_ms >= 1000:
            last_wifi_ms = t_ms
            for ap in range(4):
                lines.append(
                    f"{t_ms}\tTYPE_WIFI\tsimulated-{ap}\t0e:00:00:00:00:{ap:02x}\t{-40 - 9 * ap - idx % 7}\t5825\t{t_ms - 300}"
                )
        if idx % 150 == 0 or idx == len(data) - 1:
            lines.append(f"{t_ms}\tTYPE_WAYPOINT\t{float(row['ref_e_m']):.4f}\t{float(row['ref_n_m']):.4f}")
    lines.append(f"#\tendTime:{round(float(data[-1]['t_s']) * 1000)}")
    (HERE / "indoor-walk.txt").write_text("\n".join(lines) + "\n")


def write_tyrex(data, t0):
    folder = HERE / "tyrex-walk"
    folder.mkdir(exist_ok=True)
    files = {name: [] for name in ("accelerometer", "gyroscope", "gyroscope-calibrated", "magnetometer", "magnetometer-calibrated")}
    for row in data:
        t = f"{round((float(row['t_s']) - t0) * 1e3) / 1e3 + 0.25:.9f}"
        acc = vector(row, "acc", "mps2")
        gyro = vector(row, "gyro", "radps")
        mag = vector(row, "mag", "ut")
        files["accelerometer"].append(f"{t} {spaced(acc)}")
        files["gyroscope"].append(f"{t} {spaced([g + d for g, d in zip(gyro, OS_GYRO_DRIFT_RADPS)])} {spaced(OS_GYRO_DRIFT_RADPS)}")
        files["gyroscope-calibrated"].append(f"{t} {spaced(gyro)}")
        files["magnetometer"].append(f"{t} {spaced(mag)} {spaced(OS_MAG_BIAS_UT)}")
        files["magnetometer-calibrated"].append(f"{t} {spaced([m - b for m, b in zip(mag, OS_MAG_BIAS_UT)])}")
    for name, lines in files.items():
        (folder / f"{name}.txt").write_text("\n".join(lines) + "\n")
    (folder / "record.properties").write_text(
        f"[Device]\nManufacturer = simulated\nModel = formats.py\nOSVersion = 23\nID = 0\n\n[Time]\nStartTime = {round(t0)}\n"
    )


if __name__ == "__main__":
    main()
