#!/usr/bin/env python3
"""Writes the synthetic binary seeds (fuzz/seeds/dataflash/synthetic.bin,
fuzz/seeds/ulog/synthetic.ulg) and a synthetic DataFlash text log: small logs made
here from the formats' definitions, not taken from anyone's recording."""
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def pad(text, n):
    return text.encode().ljust(n, b"\0")[:n]


def dataflash_binary():
    out = bytearray()

    def fmt(type_id, length, name, form, columns):
        out.extend(b"\xa3\x95\x80" + struct.pack("<BB", type_id, length)
                   + pad(name, 4) + pad(form, 16) + pad(columns, 64))

    fmt(128, 89, "FMT", "BBnNZ", "Type,Length,Name,Format,Columns")
    fmt(129, 23, "PARM", "Nf", "Name,Value")
    fmt(131, 31, "IMU", "Iffffff", "TimeMS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ")
    fmt(15, 25, "MAG", "Ihhhhhhhhh", "TimeMS,MagX,MagY,MagZ,OfsX,OfsY,OfsZ,MOfsX,MOfsY,MOfsZ")
    fmt(1, 19, "ATT", "IccccCC", "TimeMS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw")
    for name, value in [("COMPASS_OFS_X", -86.9), ("COMPASS_OFS_Y", 10.5),
                        ("COMPASS_OFS_Z", 139.7), ("COMPASS_DIA_X", 1.0)]:
        out.extend(b"\xa3\x95\x81" + pad(name, 16) + struct.pack("<f", value))
    for i in range(120):
        t = 1000 + 20 * i
        yaw = 2 * math.pi * i / 120
        out.extend(b"\xa3\x95\x83" + struct.pack("<Iffffff", t, 0.0, 0.0, 0.3, 0.1, 0.2, -9.8))
        if i % 5 == 0:
            mx, my, mz = 200 * math.cos(yaw) - 87, -200 * math.sin(yaw) + 11, 400 + 140
            out.extend(b"\xa3\x95\x0f" + struct.pack("<I9h", t, int(mx), int(my), int(mz),
                                                     -87, 11, 140, 0, 0, 0))
            out.extend(b"\xa3\x95\x01" + struct.pack("<IhhhhHH", t, 0, 0, 0, 0,
                                                     int(math.degrees(yaw) * 100) % 36000,
                                                     int(math.degrees(yaw) * 100) % 36000))
    return bytes(out)


def dataflash_text():
    lines = [
        "FMT, 128, 89, FMT, BBnNZ, Type,Length,Name,Format,Columns",
        "FMT, 129, 23, PARM, Nf, Name,Value",
        "FMT, 131, 31, IMU, Iffffff, TimeMS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ",
        "FMT, 15, 25, MAG, Ihhhhhhhhh, TimeMS,MagX,MagY,MagZ,OfsX,OfsY,OfsZ,MOfsX,MOfsY,MOfsZ",
        "PARM, COMPASS_OFS_X, -86.9",
        "PARM, COMPASS_OFS_Y, 10.5",
        "PARM, COMPASS_OFS_Z, nan",
    ]
    for i in range(60):
        t = 1000 + 50 * i
        yaw = 2 * math.pi * i / 60
        lines.append(f"IMU, {t}, 0.0, 0.0, 0.3, 0.1, 0.2, -9.8")
        lines.append(f"MAG, {t}, {int(200 * math.cos(yaw))}, {int(-200 * math.sin(yaw))}, 400, "
                     "-87, 11, 140, 0, 0, 0")
    return ("ArduCopter V3.1\n\n" + "\n".join(lines) + "\n").encode()


def ulog():
    out = bytearray(b"ULog\x01\x12\x35\x01" + struct.pack("<Q", 1000))

    def msg(kind, payload):
        out.extend(struct.pack("<HB", len(payload), ord(kind)) + payload)

    msg("B", bytes(8) + bytes(8) + bytes(24))
    msg("F", b"sensor_mag:uint64_t timestamp;uint32_t device_id;float x;float y;float z;"
             b"uint8_t[4] _padding0;")
    msg("F", b"vehicle_attitude:uint64_t timestamp;float[4] q;")
    msg("I", bytes([len(b"char[3] ver_sw_release")]) + b"char[3] ver_sw_release" + b"1.14")
    msg("P", bytes([len(b"float CAL_MAG0_XOFF")]) + b"float CAL_MAG0_XOFF" + struct.pack("<f", 0.1))
    msg("A", struct.pack("<BH", 0, 0) + b"sensor_mag")
    msg("A", struct.pack("<BH", 0, 1) + b"vehicle_attitude")
    for i in range(100):
        t = 1_000_000 + 20_000 * i
        yaw = 2 * math.pi * i / 100
        msg("D", struct.pack("<HQIfff", 0, t, 1234, 0.2 * math.cos(yaw), -0.2 * math.sin(yaw), 0.4)
            + bytes(4))
        msg("D", struct.pack("<HQffff", 1, t, math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)))
    return bytes(out)


for path, data in [("seeds/dataflash/synthetic.bin", dataflash_binary()),
                   ("seeds/dataflash/synthetic.log", dataflash_text()),
                   ("seeds/ulog/synthetic.ulg", ulog())]:
    with open(os.path.join(HERE, path), "wb") as f:
        f.write(data)
