//! The plots' zoom ([`compass_pdr::plot::zoom`]) on real recordings, not only on the
//! simulator's walks: a car's 87-minute drive at 1 Hz and a phone's indoor loop, each
//! folder's files imported together. Zoomed tenfold about the middle, the time plots show
//! a tenth of the log and read the time under the pointer; the trajectory keeps equal
//! axes. Skipped with a message when `../shared/data` is absent.
#![cfg(not(target_arch = "wasm32"))]

mod common;

use common::shared_data;
use compass_pdr::pdr::PdrOptions;
use compass_pdr::pipeline;
use compass_pdr::plot::pdr::draw_trajectory;
use compass_pdr::plot::zoom::{PlotFrame, Zoom};
use compass_pdr::plot::{draw_field_magnitude_of, draw_heading_error};
use plotters::prelude::{IntoDrawingArea, SVGBackend};

#[test]
fn zoomed_plots_of_real_logs_show_the_window_asked_for() {
    let Some(data) = shared_data() else { return };
    for folder in ["vehicle-pixel6a", "phyphox-hallway-loop"] {
        let dir = data.join(folder);
        let mut paths: Vec<_> = std::fs::read_dir(&dir)
            .expect("readable directory")
            .filter_map(|entry| entry.ok().map(|entry| entry.path()))
            .filter(|path| path.extension().is_some_and(|ext| ext == "csv"))
            .collect();
        paths.sort();
        let import = common::import_paths(&paths);
        let mut options = PdrOptions::default();
        options.heading_options.neural = false;
        let analysis = pipeline::analyse(&import, &options).expect("analyses");
        let pdr = analysis
            .pdr
            .as_ref()
            .and_then(|pdr| pdr.as_ref().ok())
            .expect("dead-reckoned");
        let tenfold = Zoom::WHOLE.zoomed((0.5, 0.5), 10.0, false);
        let map_zoom = Zoom::WHOLE.zoomed((0.5, 0.5), 4.0, true);
        let span = |frame: &PlotFrame| frame.x.end - frame.x.start;
        let mut svg = String::new();
        let root = SVGBackend::with_string(&mut svg, (560, 440)).into_drawing_area();
        for draw in [draw_heading_error, draw_field_magnitude_of] {
            let whole = draw(&root, &analysis.calibration, Zoom::WHOLE).expect("drawn");
            let zoomed = draw(&root, &analysis.calibration, tenfold).expect("drawn");
            assert!(
                (span(&zoomed) - span(&whole) / 10.0).abs() < 1e-6 * span(&whole),
                "{folder}: {zoomed:?} against {whole:?}"
            );
            let middle_px = (
                f64::from(zoomed.x_px.start + zoomed.x_px.end) / 2.0,
                f64::from(zoomed.y_px.start + zoomed.y_px.end) / 2.0,
            );
            let (time_s, _) = zoomed.value_at(middle_px).expect("inside the plot");
            let middle_s = (whole.x.start + whole.x.end) / 2.0;
            assert!(
                (time_s - middle_s).abs() < span(&zoomed) / 20.0,
                "{folder}: {time_s} s under the middle, not {middle_s} s"
            );
            let readout = zoomed.readout(middle_px).expect("inside the plot");
            assert!(readout.starts_with("time (s) "), "{readout}");
        }
        let whole = draw_trajectory(&root, pdr, Zoom::WHOLE).expect("drawn");
        let zoomed = draw_trajectory(&root, pdr, map_zoom).expect("drawn");
        let metres_per_px = |frame: &PlotFrame| {
            (
                span(frame) / f64::from(frame.x_px.end - frame.x_px.start),
                (frame.y.end - frame.y.start) / f64::from(frame.y_px.end - frame.y_px.start),
            )
        };
        let (x_scale, y_scale) = metres_per_px(&zoomed);
        assert!(
            (x_scale / y_scale - 1.0).abs() < 0.02,
            "{folder}: {x_scale} and {y_scale} m per pixel"
        );
        assert!((metres_per_px(&whole).0 / x_scale - 4.0).abs() < 1e-6);
    }
}
