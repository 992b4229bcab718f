#!/bin/sh
# Fills fuzz/corpus/<target>/ (gitignored) with the committed seeds and with short
# excerpts of the real recordings in ../shared/data (first 200 lines of text logs, first
# 64 KiB of binary logs). The recordings stay outside the repository (their licences
# differ from the project's); without them only the seeds are used.
set -eu
cd "$(dirname "$0")"
D=${DATA:-../../shared/data}
for t in delimited nmea serial_lines tagged_lines dataflash ulog import; do
    mkdir -p "corpus/$t"
    [ -d "seeds/$t" ] && cp seeds/$t/* "corpus/$t/" 2>/dev/null || true
done
[ -d "$D" ] || { echo "no $D: corpus holds only the seeds"; exit 0; }
lines() { head -n 200 "$1" > "$2"; }
lines "$D/vehicle-pixel6a/2023-08-09_12-47-42.csv" corpus/delimited/pixel6a.csv
lines "$D/hmc5883l-sphere/full-sphere/hmc5883l_compass.csv" corpus/delimited/hmc5883l.csv
lines "$D/phyphox-hallway-loop/Magnetometer.csv" corpus/delimited/phyphox-mag.csv
lines "$D/qmc5883l-calibration/noisy_raw_data.csv" corpus/delimited/qmc5883l.csv
lines "$D/sensorlogger-walk-ethz/MagnetometerUncalibrated.csv" corpus/delimited/sensorlogger-mag.csv
lines "$D/tyrex-attitude/Thibaud_Nexus5_Dist_Texting/magnetometer.txt" corpus/serial_lines/tyrex-mag.txt
lines "$D/msft-indoor-2020/site1/F1/5dd9ef979191710006b57086.txt" corpus/tagged_lines/msft-f1.txt
lines "$D/msft-indoor-2020/site1/F4/5ddb6573c5b77e0006b17932.txt" corpus/tagged_lines/msft-f4.txt
head -c 65536 "$D/ardupilot-copter-log171/log171.bin" > corpus/dataflash/log171-64k.bin
cp "$D/ardupilot-text-log/nan.log" corpus/dataflash/nan.log
head -c 65536 "$D/px4-ulog/sample_log_small.ulg" > corpus/ulog/sample_log_small-64k.ulg
head -c 65536 "$D/px4-ulog/sample.ulg" > corpus/ulog/sample-64k.ulg
# The import target reads everything.
for t in delimited nmea serial_lines tagged_lines dataflash ulog; do
    cp corpus/$t/* corpus/import/
done
echo "corpus ready"
