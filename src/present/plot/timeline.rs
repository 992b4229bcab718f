//! The timeline strip the page's controls are brushed on: the log's time axis, the
//! train part (blue) and the check part, the GNSS outages (orange), and a tick for each
//! GNSS fix.
//!
//! It is drawn with the area's own pixel coordinates (no chart), so that the page maps a
//! pointer position back to a time with [`Timeline::time_at`], the inverse of the
//! drawing's own [`Timeline::x_at`].

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::PlotError;
use crate::pdr::fusion::Outage;

const TRAIN_COLOR: RGBColor = RGBColor(30, 100, 200);
const CHECK_COLOR: RGBColor = RGBColor(200, 210, 225);
const OUTAGE_COLOR: RGBColor = RGBColor(230, 120, 30);

/// Pixels left and right of the time axis (room for the labels).
const LEFT_PX: f64 = 70.0;
const RIGHT_PX: f64 = 20.0;

/// What the strip shows, and where its time axis lies.
#[derive(Debug, Clone, PartialEq)]
pub struct Timeline {
    pub start_s: f64,
    pub end_s: f64,
    /// The end of the train part, if the log is split.
    pub train_until_s: Option<f64>,
    pub outages: Vec<Outage>,
    pub gnss_times_s: Vec<f64>,
}

impl Timeline {
    /// The horizontal pixel of time `t_s` on an area `width_px` wide.
    pub fn x_at(&self, t_s: f64, width_px: f64) -> f64 {
        let span_s = (self.end_s - self.start_s).max(f64::MIN_POSITIVE);
        let fraction = ((t_s - self.start_s) / span_s).clamp(0.0, 1.0);
        LEFT_PX + fraction * (width_px - LEFT_PX - RIGHT_PX).max(1.0)
    }

    /// The time at horizontal pixel `x_px` on an area `width_px` wide (clamped to the
    /// log).
    pub fn time_at(&self, x_px: f64, width_px: f64) -> f64 {
        let fraction =
            ((x_px - LEFT_PX) / (width_px - LEFT_PX - RIGHT_PX).max(1.0)).clamp(0.0, 1.0);
        self.start_s + fraction * (self.end_s - self.start_s)
    }
}

pub fn draw_timeline<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    timeline: &Timeline,
) -> Result<(), PlotError> {
    let error = PlotError::from_backend::<DrawingAreaErrorKind<DB::ErrorType>>("timeline");
    area.fill(&WHITE).map_err(&error)?;
    let (width_px, height_px) = area.dim_in_pixel();
    let width = f64::from(width_px);
    let (bar_top, bar_bottom) = (18, height_px as i32 - 26);
    let x = |t_s: f64| timeline.x_at(t_s, width).round() as i32;
    let split_s = timeline.train_until_s.unwrap_or(timeline.end_s);
    area.draw(&Rectangle::new(
        [(x(timeline.start_s), bar_top), (x(split_s), bar_bottom)],
        TRAIN_COLOR.mix(0.35).filled(),
    ))
    .map_err(&error)?;
    if split_s < timeline.end_s {
        area.draw(&Rectangle::new(
            [(x(split_s), bar_top), (x(timeline.end_s), bar_bottom)],
            CHECK_COLOR.filled(),
        ))
        .map_err(&error)?;
        area.draw(&PathElement::new(
            vec![(x(split_s), bar_top - 6), (x(split_s), bar_bottom + 4)],
            TRAIN_COLOR.stroke_width(3),
        ))
        .map_err(&error)?;
    }
    for &t_s in &timeline.gnss_times_s {
        area.draw(&PathElement::new(
            vec![(x(t_s), bar_bottom - 8), (x(t_s), bar_bottom)],
            BLACK.mix(0.35).stroke_width(1),
        ))
        .map_err(&error)?;
    }
    for outage in &timeline.outages {
        area.draw(&Rectangle::new(
            [(x(outage.start_s), bar_top), (x(outage.end_s), bar_bottom)],
            OUTAGE_COLOR.mix(0.55).filled(),
        ))
        .map_err(&error)?;
    }
    let label = TextStyle::from(("sans-serif", 13).into_font()).color(&BLACK);
    let caption = match timeline.train_until_s {
        Some(split_s) => format!("train until {split_s:.0} s, then check"),
        None => "no check part".to_string(),
    };
    area.draw(&Text::new(
        format!(
            "{caption}; {} GNSS outage{}",
            timeline.outages.len(),
            if timeline.outages.len() == 1 { "" } else { "s" }
        ),
        (x(timeline.start_s), 2),
        label.clone(),
    ))
    .map_err(&error)?;
    area.draw(&Text::new("time (s)", (4, bar_bottom + 6), label.clone()))
        .map_err(&error)?;
    let step_s = nice_step((timeline.end_s - timeline.start_s) / 8.0);
    let tick_style = label.pos(Pos::new(HPos::Center, VPos::Top));
    let mut tick_s = (timeline.start_s / step_s).ceil() * step_s;
    while tick_s <= timeline.end_s {
        area.draw(&PathElement::new(
            vec![(x(tick_s), bar_bottom), (x(tick_s), bar_bottom + 4)],
            BLACK.stroke_width(1),
        ))
        .map_err(&error)?;
        area.draw(&Text::new(
            format!("{tick_s:.0}"),
            (x(tick_s), bar_bottom + 6),
            tick_style.clone(),
        ))
        .map_err(&error)?;
        tick_s += step_s;
    }
    Ok(())
}

/// 1, 2 or 5 times a power of ten, at least `rough` (and at least 1 s).
fn nice_step(rough: f64) -> f64 {
    if !(rough.is_finite() && rough > 1.0) {
        return 1.0;
    }
    let power = 10f64.powf(rough.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|factor| factor * power)
        .find(|step| *step >= rough)
        .unwrap_or(10.0 * power)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_and_times_map_back_and_forth() {
        let timeline = Timeline {
            start_s: 10.0,
            end_s: 190.0,
            train_until_s: Some(100.0),
            outages: vec![Outage {
                start_s: 40.0,
                end_s: 60.0,
            }],
            gnss_times_s: vec![20.0, 21.0],
        };
        for t_s in [10.0, 55.5, 190.0] {
            let x = timeline.x_at(t_s, 1200.0);
            assert!((timeline.time_at(x, 1200.0) - t_s).abs() < 1e-9);
        }
        assert_eq!(timeline.time_at(0.0, 1200.0), 10.0);
        assert_eq!(timeline.time_at(5000.0, 1200.0), 190.0);
        let mut svg = String::new();
        {
            let area = SVGBackend::with_string(&mut svg, (1200, 90)).into_drawing_area();
            draw_timeline(&area, &timeline).expect("draws");
        }
        assert!(svg.contains("train until 100 s, then check; 1 GNSS outage"));
        assert_eq!(nice_step(22.5), 50.0);
        assert_eq!(nice_step(0.3), 1.0);
    }
}
