"""Writes igrf14_field.csv: the Earth's field from IGRF-14 (the International
Geomagnetic Reference Field, 14th generation, as the `ppigrf` package evaluates it) at
random places and dates, an independent check of how compass-pdr's World Magnetic Model
answers dates outside the years its models cover (src/calib/wmm.rs, tests in
tests/independent.rs). IGRF-14's coefficients are definitive up to 2020, so the dates
before the WMM2020 epoch are the field as it was.

    python3 -m pip install ppigrf numpy   # 2.1.0 and 2.x were used
    python3 tests/data/igrf14_field.py > tests/data/igrf14_field.csv

Places are uniform over the sphere's area between 80° S and 80° N; dates uniform
over 1990-2019 (the years before the bundled models) and 2020-2024 (inside them, to
compare the two models where both hold). Columns: date, latitude and longitude (°,
east positive), and IGRF-14's declination and inclination (°) and total and horizontal
intensity (µT) at sea level (height 0 above the geoid, as ppigrf takes it).
"""

import datetime
import math

import numpy as np
import ppigrf

rng = np.random.default_rng(20261128)
print("date,lat_deg,lon_deg,declination_deg,inclination_deg,total_ut,horizontal_ut")
for idx in range(600):
    lat = math.degrees(math.asin(rng.uniform(math.sin(math.radians(-80)), math.sin(math.radians(80)))))
    lon = rng.uniform(-180.0, 180.0)
    if idx < 500:
        start, end = datetime.date(1990, 1, 1), datetime.date(2019, 12, 31)
    else:
        start, end = datetime.date(2020, 1, 1), datetime.date(2024, 12, 31)
    date = start + datetime.timedelta(days=int(rng.integers(0, (end - start).days + 1)))
    east, north, up = (
        float(np.ravel(value)[0])
        for value in ppigrf.igrf(lon, lat, 0.0, datetime.datetime(date.year, date.month, date.day))
    )
    horizontal = math.hypot(east, north)
    print(
        f"{date.isoformat()},{lat:.4f},{lon:.4f},{math.degrees(math.atan2(east, north)):.4f},"
        f"{math.degrees(math.atan2(-up, horizontal)):.4f},{math.sqrt(horizontal**2 + up**2) / 1000:.4f},"
        f"{horizontal / 1000:.4f}"
    )
