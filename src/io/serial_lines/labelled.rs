//! Labelled lines ([`super`]): the Arduino Serial Plotter's `label:value` pairs
//! (arduino/Arduino `build/shared/ArduinoSerialPlotterProtocol.md`) and CircuitPython's
//! `X: … Y: … Z: …` with a unit that names the sensor
//! (adafruit/Adafruit_CircuitPython_LIS3MDL `examples/lis3mdl_simpletest.py` and
//! `examples/lis3mdl_lsm6ds_test.py`). A line is cut into items, the items into runs
//! that follow a sensor name, and each label becomes a sensor axis with its unit.

use nalgebra::Vector3;

use super::names::{quantity_of_name, Normalized, SUMMARY_WORDS, TEMP_NAMES};
use super::units::{
    number, number_with_unit, set_vector, unit_of, Quantity, Unit, CELSIUS, DEGPS, GAUSS,
    MICROTESLA, MPS2, NANOTESLA, RADPS,
};
use super::{LineError, LineFormat, SensorSample, MAX_FIELDS};

/// What a Serial Plotter label names.
#[derive(Debug, Clone, Copy, PartialEq)]
enum LabelKind {
    /// An axis of a sensor (`None`: a bare `x`, `y` or `z`), with the unit the label
    /// itself carries (`mag_x_ut`).
    Axis {
        quantity: Option<Quantity>,
        axis: usize,
        unit: Option<Unit>,
    },
    Temp {
        unit: Option<Unit>,
    },
    Unknown,
}

/// Units written as label suffixes, longest first so that `mps2` wins over `ms2`.
const LABEL_UNIT_SUFFIXES: [(&str, Unit); 10] = [
    ("gauss", GAUSS),
    ("radps", RADPS),
    ("degps", DEGPS),
    ("mps2", MPS2),
    ("rads", RADPS),
    ("degs", DEGPS),
    ("ms2", MPS2),
    ("dps", DEGPS),
    ("ut", MICROTESLA),
    ("nt", NANOTESLA),
];

fn classify_label(label: &str) -> LabelKind {
    let Some(normalized) = Normalized::new(label) else {
        return LabelKind::Unknown;
    };
    let name = normalized.as_str();
    for (suffix, unit) in [("", None), ("degc", Some(CELSIUS)), ("c", Some(CELSIUS))] {
        if let Some(stem) = name.strip_suffix(suffix) {
            if TEMP_NAMES.contains(&stem) {
                return LabelKind::Temp { unit };
            }
        }
    }
    let (stem, unit) = LABEL_UNIT_SUFFIXES
        .iter()
        .find_map(|&(suffix, unit)| {
            let stem = name.strip_suffix(suffix)?;
            stem.ends_with(['x', 'y', 'z'])
                .then_some((stem, Some(unit)))
        })
        .unwrap_or((name, None));
    let axis = match stem.bytes().last() {
        Some(b'x') => 0,
        Some(b'y') => 1,
        Some(b'z') => 2,
        _ => return LabelKind::Unknown,
    };
    let sensor_name = stem.get(..stem.len() - 1).unwrap_or("");
    if sensor_name.is_empty() {
        return LabelKind::Axis {
            quantity: None,
            axis,
            unit,
        };
    }
    match quantity_of_name(sensor_name, true) {
        Some(Quantity::Temp) | None => LabelKind::Unknown,
        Some(quantity) => LabelKind::Axis {
            quantity: Some(quantity),
            axis,
            unit,
        },
    }
}

/// One part of a labelled line.
#[derive(Debug, Clone, Copy)]
enum Item<'a> {
    Pair {
        label: &'a str,
        value: f64,
        unit: Option<Unit>,
    },
    /// `label:` with no number after it (a prefix such as `Acceleration:`).
    Label(&'a str),
    /// A number without a label; only its presence matters (it makes the line
    /// ambiguous).
    Number,
    Word(&'a str),
}

fn is_separator(byte: u8) -> bool {
    matches!(byte, b',' | b';' | b' ' | b'\t')
}

/// Splits a labelled line into items. Separators are commas, semicolons, spaces and
/// tabs; spaces may stand around the colon (`Label : Value` in Arduino's description).
fn scan_items<'a>(text: &'a str, items: &mut [Item<'a>; MAX_FIELDS]) -> Result<usize, LineError> {
    let bytes = text.as_bytes();
    let mut n_items = 0usize;
    let mut idx = 0usize;
    let skip_blanks = |mut at: usize| {
        while matches!(bytes.get(at), Some(b' ' | b'\t')) {
            at += 1;
        }
        at
    };
    let word_end = |mut at: usize| {
        while let Some(&byte) = bytes.get(at) {
            if is_separator(byte) || byte == b':' {
                break;
            }
            at += 1;
        }
        at
    };
    loop {
        while bytes.get(idx).is_some_and(|&byte| is_separator(byte)) {
            idx += 1;
        }
        if idx >= bytes.len() {
            break;
        }
        let start = idx;
        let end = word_end(start);
        let word = text.get(start..end).unwrap_or("");
        let after_blanks = skip_blanks(end);
        let item = if bytes.get(after_blanks) == Some(&b':') {
            let value_start = skip_blanks(after_blanks + 1);
            let value_end = word_end(value_start);
            let value_word = text.get(value_start..value_end).unwrap_or("");
            let value = number(value_word)
                .map(|value| (value, None))
                .or_else(|| number_with_unit(value_word).map(|(value, unit)| (value, Some(unit))));
            match value {
                Some((value, unit)) => {
                    idx = value_end;
                    Item::Pair {
                        label: word,
                        value,
                        unit,
                    }
                }
                None => {
                    idx = after_blanks + 1;
                    Item::Label(word)
                }
            }
        } else {
            idx = end;
            match number(word) {
                Some(_) => Item::Number,
                None => {
                    // A unit right after a value belongs to that value (`X: 1.0 uT`).
                    let previous = n_items.checked_sub(1).and_then(|last| items.get_mut(last));
                    if let (
                        Some(Item::Pair {
                            unit: unit @ None, ..
                        }),
                        Some(found),
                    ) = (previous, unit_of(word))
                    {
                        *unit = Some(found);
                        continue;
                    }
                    Item::Word(word)
                }
            }
        };
        let Some(slot) = items.get_mut(n_items) else {
            return Err(LineError::TooManyFields { max: MAX_FIELDS });
        };
        *slot = item;
        n_items += 1;
    }
    Ok(n_items)
}

/// Adds `unit` to a pool that must hold one unit only.
fn pool_unit(pool: &mut Option<Unit>, unit: Unit, what: &'static str) -> Result<(), LineError> {
    match pool {
        Some(existing) if existing.to_si != unit.to_si || existing.quantity != unit.quantity => {
            Err(LineError::UnitConflict {
                unit: unit.name,
                what,
            })
        }
        Some(_) => Ok(()),
        None => {
            *pool = Some(unit);
            Ok(())
        }
    }
}

fn quantity_slot(quantity: Quantity) -> Option<usize> {
    match quantity {
        Quantity::Acc => Some(0),
        Quantity::Gyro => Some(1),
        Quantity::Mag => Some(2),
        Quantity::Temp => None,
    }
}

const VECTOR_QUANTITIES: [Quantity; 3] = [Quantity::Acc, Quantity::Gyro, Quantity::Mag];

/// A run of pairs after a sensor name: `Gyro X: 1 Y: 2 Z: 3 rad/s`. Bare `x`, `y`, `z`
/// take their sensor from the run they are in.
#[derive(Debug, Clone, Copy, Default)]
struct Group {
    /// The sensor a word before the run names.
    hint: Option<Quantity>,
    hint_is_ambiguous: bool,
    /// The unit written for the bare axes of the run.
    unit: Option<Unit>,
    n_bare: usize,
}

/// More runs than a line has; later ones merge into the last.
const MAX_GROUPS: usize = 8;

/// Serial Plotter pairs and CircuitPython's `X: Y: Z: unit`.
pub(super) fn parse_labelled<'a>(
    text: &'a str,
    on_ignored: &mut dyn FnMut(&'a str),
) -> Result<SensorSample, LineError> {
    let mut items = [Item::Number; MAX_FIELDS];
    let n_items = scan_items(text, &mut items)?;
    let items = items.get(..n_items).unwrap_or_default();
    if items.iter().any(|item| matches!(item, Item::Number))
        && items.iter().any(|item| matches!(item, Item::Pair { .. }))
    {
        return Err(LineError::MixedPairsAndNumbers);
    }

    let Runs {
        mut groups,
        group_of_item,
        n_pairs,
    } = runs_of(items)?;
    if n_pairs == 0 {
        return Err(LineError::Unrecognised);
    }
    let (mut pools, n_named_axes) = pool_units(items, &group_of_item, &mut groups)?;
    let (bare_quantities, all_bare_have_units) =
        quantities_of_bare_axes(&groups, n_pairs, &mut pools)?;
    let n_bare: usize = groups.iter().map(|group| group.n_bare).sum();

    let mut values: [[Option<f64>; 3]; 3] = [[None; 3]; 3];
    let mut sample = SensorSample::empty(LineFormat::SerialPlotter);
    for (idx, item) in items.iter().enumerate() {
        let Item::Pair { label, value, unit } = *item else {
            continue;
        };
        match classify_label(label) {
            LabelKind::Axis { quantity, axis, .. } => {
                let bare_quantity = group_of_item
                    .get(idx)
                    .and_then(|&group| bare_quantities.get(group))
                    .copied()
                    .flatten();
                let Some(quantity) = quantity.or(bare_quantity) else {
                    on_ignored(label);
                    sample.n_ignored_labels += 1;
                    continue;
                };
                let slot = quantity_slot(quantity)
                    .and_then(|slot| values.get_mut(slot))
                    .and_then(|axes| axes.get_mut(axis));
                if let Some(slot) = slot {
                    if slot.is_some() {
                        return Err(LineError::DuplicateLabel {
                            quantity: quantity.name(),
                            axis: ['x', 'y', 'z'].get(axis).copied().unwrap_or('?'),
                        });
                    }
                    *slot = Some(value);
                }
            }
            LabelKind::Temp { unit: suffix_unit } => {
                if sample.temp_c.is_some() {
                    return Err(LineError::DuplicateLabel {
                        quantity: Quantity::Temp.name(),
                        axis: ' ',
                    });
                }
                let to_si = suffix_unit.or(unit).map_or(1.0, |unit| unit.to_si);
                sample.temp_c = Some(value * to_si);
            }
            LabelKind::Unknown => {
                on_ignored(label);
                sample.n_ignored_labels += 1;
            }
        }
    }

    for (quantity, (axes, pool)) in VECTOR_QUANTITIES.iter().zip(values.iter().zip(pools)) {
        match *axes {
            [Some(x), Some(y), Some(z)] => {
                set_vector(&mut sample, *quantity, Vector3::new(x, y, z), pool);
            }
            [None, None, None] => {}
            _ => {
                return Err(LineError::IncompleteVector {
                    quantity: quantity.name(),
                })
            }
        }
    }
    let has_values = sample.acc_in_sensor_mps2.is_some()
        || sample.gyro_in_sensor_radps.is_some()
        || sample.mag_in_sensor_ut.is_some()
        || sample.temp_c.is_some();
    if !has_values {
        return Err(LineError::NoKnownLabels);
    }
    if n_bare > 0 && all_bare_have_units && n_named_axes == 0 {
        sample.format = LineFormat::CircuitPythonXyz;
    }
    Ok(sample)
}

/// A line's runs, which run each of its items is in, and how many pairs it has.
struct Runs {
    groups: [Group; MAX_GROUPS],
    group_of_item: [usize; MAX_FIELDS],
    n_pairs: usize,
}

/// The words around the pairs: a sensor name starts a new run, a unit belongs to
/// the run it is in, and a summary word means the line is no reading.
fn runs_of(items: &[Item<'_>]) -> Result<Runs, LineError> {
    let mut groups = [Group::default(); MAX_GROUPS];
    let mut group_of_item = [0usize; MAX_FIELDS];
    let mut current = 0usize;
    let mut n_pairs_in_current = 0usize;
    let mut n_pairs = 0usize;
    for (idx, item) in items.iter().enumerate() {
        match *item {
            Item::Word(word) | Item::Label(word) => {
                if let Some(unit) = unit_of(word) {
                    if let Some(group) = groups.get_mut(current) {
                        pool_unit(&mut group.unit, unit, "x, y, z values")?;
                    }
                } else if let Some(normalized) = Normalized::new(word) {
                    let name = normalized.as_str();
                    if SUMMARY_WORDS.contains(&name) {
                        return Err(LineError::Summary);
                    }
                    if let Some(quantity) = quantity_of_name(name, false) {
                        if n_pairs_in_current > 0 {
                            current = (current + 1).min(MAX_GROUPS - 1);
                            n_pairs_in_current = 0;
                        }
                        if let Some(group) = groups.get_mut(current) {
                            if group.hint.is_some_and(|hint| hint != quantity) {
                                group.hint_is_ambiguous = true;
                            }
                            group.hint = Some(quantity);
                        }
                    }
                }
            }
            Item::Pair { .. } => {
                n_pairs += 1;
                n_pairs_in_current += 1;
            }
            Item::Number => {}
        }
        if let Some(slot) = group_of_item.get_mut(idx) {
            *slot = current;
        }
    }
    Ok(Runs {
        groups,
        group_of_item,
        n_pairs,
    })
}

/// Units per quantity, from label suffixes and units written after values; the bare
/// axes are counted in their run, with the units written for them. Also returns how
/// many labels name their sensor.
fn pool_units(
    items: &[Item<'_>],
    group_of_item: &[usize; MAX_FIELDS],
    groups: &mut [Group; MAX_GROUPS],
) -> Result<([Option<Unit>; 3], usize), LineError> {
    let mut pools: [Option<Unit>; 3] = [None; 3];
    let mut n_named_axes = 0usize;
    for (idx, item) in items.iter().enumerate() {
        let Item::Pair { label, unit, .. } = *item else {
            continue;
        };
        match classify_label(label) {
            LabelKind::Axis {
                quantity: Some(quantity),
                unit: suffix_unit,
                ..
            } => {
                n_named_axes += 1;
                if let Some(unit) = suffix_unit.or(unit) {
                    if unit.quantity != quantity {
                        return Err(LineError::UnitConflict {
                            unit: unit.name,
                            what: quantity.name(),
                        });
                    }
                    if let Some(pool) = quantity_slot(quantity).and_then(|slot| pools.get_mut(slot))
                    {
                        pool_unit(pool, unit, quantity.name())?;
                    }
                }
            }
            LabelKind::Axis {
                quantity: None,
                unit: suffix_unit,
                ..
            } => {
                let group = group_of_item
                    .get(idx)
                    .and_then(|&group| groups.get_mut(group));
                if let Some(group) = group {
                    group.n_bare += 1;
                    if let Some(unit) = suffix_unit.or(unit) {
                        pool_unit(&mut group.unit, unit, "x, y, z values")?;
                    }
                }
            }
            LabelKind::Temp { unit: suffix_unit } => {
                if let Some(unit) = suffix_unit.or(unit) {
                    if unit.quantity != Quantity::Temp {
                        return Err(LineError::UnitConflict {
                            unit: unit.name,
                            what: Quantity::Temp.name(),
                        });
                    }
                }
            }
            LabelKind::Unknown => {}
        }
    }
    Ok((pools, n_named_axes))
}

/// Bare x, y, z of a run: the unit says the sensor, else the name before the run,
/// else they are the magnetometer when they are the line's only values. Also returns
/// whether every run of bare axes has a unit that names its sensor.
fn quantities_of_bare_axes(
    groups: &[Group; MAX_GROUPS],
    n_pairs: usize,
    pools: &mut [Option<Unit>; 3],
) -> Result<([Option<Quantity>; MAX_GROUPS], bool), LineError> {
    let mut bare_quantities: [Option<Quantity>; MAX_GROUPS] = [None; MAX_GROUPS];
    let mut all_bare_have_units = true;
    for (group, bare_quantity) in groups.iter().zip(bare_quantities.iter_mut()) {
        if group.n_bare == 0 {
            continue;
        }
        let hint = group
            .hint
            .filter(|hint| !group.hint_is_ambiguous && *hint != Quantity::Temp);
        *bare_quantity = if let Some(unit) = group.unit {
            if unit.quantity == Quantity::Temp {
                return Err(LineError::UnitConflict {
                    unit: unit.name,
                    what: "x, y, z values",
                });
            }
            if let Some(hint) = hint.filter(|hint| *hint != unit.quantity) {
                return Err(LineError::UnitConflict {
                    unit: unit.name,
                    what: hint.name(),
                });
            }
            Some(unit.quantity)
        } else if hint.is_some() {
            hint
        } else if n_pairs == 3 && group.n_bare == 3 {
            Some(Quantity::Mag)
        } else {
            None
        };
        all_bare_have_units &= group.unit.is_some() && bare_quantity.is_some();
        if let (Some(quantity), Some(unit)) = (*bare_quantity, group.unit) {
            if let Some(pool) = quantity_slot(quantity).and_then(|slot| pools.get_mut(slot)) {
                pool_unit(pool, unit, quantity.name())?;
            }
        }
    }
    Ok((bare_quantities, all_bare_have_units))
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::super::parse_line;
    use super::super::tests::{assert_close, sample};
    use super::*;

    #[test]
    fn golden_serial_plotter_pairs() {
        let s = sample("mx:12.5,my:-3.25,mz:40.0");
        assert_eq!(s.format, LineFormat::SerialPlotter);
        assert_close(s.mag_in_sensor_ut, [12.5, -3.25, 40.0], "mag");

        let s = sample("MagX:12.5 MagY:-3.2 MagZ:40");
        assert_close(s.mag_in_sensor_ut, [12.5, -3.2, 40.0], "mag");

        let s = sample("AccX:0.1\tAccY:0.2\tAccZ:9.8\tgyro_x:0.01\tgyro_y:0.02\tgyro_z:0.03\tmag_x:1\tmag_y:2\tmag_z:3\ttemp:25.5\tloop:7");
        assert_close(s.acc_in_sensor_mps2, [0.1, 0.2, 9.8], "acc");
        assert_close(s.gyro_in_sensor_radps, [0.01, 0.02, 0.03], "gyro");
        assert_close(s.mag_in_sensor_ut, [1.0, 2.0, 3.0], "mag");
        assert_eq!(s.temp_c, Some(25.5));
        assert_eq!(s.n_ignored_labels, 1);

        // Units in the labels, and spaces around the colon.
        let s = sample("gyro_x_dps : 90, gyro_y_dps : 0, gyro_z_dps : -90, mag_x_gauss:0.5 mag_y_gauss:0 mag_z_gauss:-0.25");
        assert_close(s.gyro_in_sensor_radps, [PI / 2.0, 0.0, -PI / 2.0], "gyro");
        assert_close(s.mag_in_sensor_ut, [50.0, 0.0, -25.0], "mag");
        assert!(!s.gyro_unit_assumed && !s.mag_unit_assumed);

        // Bare x, y, z are the magnetometer when they are the only values.
        let s = sample("x:1 y:2 z:3");
        assert_close(s.mag_in_sensor_ut, [1.0, 2.0, 3.0], "bare mag");
        assert!(s.mag_unit_assumed);

        assert_eq!(
            parse_line("mx:1 my:2"),
            Err(LineError::IncompleteVector {
                quantity: "magnetometer"
            })
        );
        assert_eq!(parse_line("heading:123.4"), Err(LineError::NoKnownLabels));
        assert_eq!(
            parse_line("Orientation: 12.0, 3.0, 4.0"),
            Err(LineError::MixedPairsAndNumbers)
        );
    }

    #[test]
    fn golden_circuitpython_xyz_with_units() {
        let s = sample("X:      1.00, Y:      2.00, Z:      3.00 uT");
        assert_eq!(s.format, LineFormat::CircuitPythonXyz);
        assert_close(s.mag_in_sensor_ut, [1.0, 2.0, 3.0], "mag");
        assert!(!s.mag_unit_assumed);

        assert_close(
            sample("X:1.00 Y:2.00 Z:3.00 uT").mag_in_sensor_ut,
            [1.0, 2.0, 3.0],
            "mag",
        );
        let s = sample("Acceleration: X:   0.10, Y:  -0.20, Z:   9.80 m/s^2");
        assert_close(s.acc_in_sensor_mps2, [0.1, -0.2, 9.8], "acc");
        let s = sample("Gyro          X:   0.01, Y:   0.02, Z:  -0.03 rad/s");
        assert_close(s.gyro_in_sensor_radps, [0.01, 0.02, -0.03], "gyro");
        let s = sample("X: 90 Y: 0 Z: -180 deg/s");
        assert_close(s.gyro_in_sensor_radps, [PI / 2.0, 0.0, -PI], "gyro °/s");
        let s = sample("X: 0.5 Y: 0.1 Z: -0.2 gauss");
        assert_close(s.mag_in_sensor_ut, [50.0, 10.0, -20.0], "gauss");
        let s = sample("X: 20000 Y: -5000 Z: 40000 nT");
        assert_close(s.mag_in_sensor_ut, [20.0, -5.0, 40.0], "nT");
        let s = sample("Accel X: 0.1 Y: 0.2 Z: 9.8 m/s^2 Gyro X: 90 Y: 0 Z: 0 deg/s");
        assert_eq!(s.format, LineFormat::CircuitPythonXyz);
        assert_close(s.acc_in_sensor_mps2, [0.1, 0.2, 9.8], "acc run");
        assert_close(s.gyro_in_sensor_radps, [PI / 2.0, 0.0, 0.0], "gyro run");
        let s = sample("Accel X: 0.1 Y: 0.2 Z: 9.8 Mag X: 20 Y: 0 Z: -40");
        assert_eq!(s.format, LineFormat::SerialPlotter);
        assert_close(s.mag_in_sensor_ut, [20.0, 0.0, -40.0], "mag run");
        assert!(s.acc_unit_assumed && s.mag_unit_assumed);
        let s = sample("Temperature: 25.000C");
        assert_eq!(s.temp_c, Some(25.0));

        assert_eq!(
            parse_line("  Final Calibration: X:  1.00 Y:  2.00 Z:  3.00 uT"),
            Err(LineError::Summary)
        );
        assert!(matches!(
            parse_line("Magnetic X: 1 Y: 2 Z: 3 m/s^2"),
            Err(LineError::UnitConflict { .. })
        ));
    }
}
