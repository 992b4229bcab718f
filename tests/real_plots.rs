//! The plots' zoom ([`compass_pdr::present::plot::zoom`]) on real recordings, not only on the
//! simulator's walks: a car's 87-minute drive at 1 Hz and a phone's indoor loop, each
//! folder's files imported together. Zoomed tenfold about the middle, the time plots show
//! a tenth of the log and read the time under the pointer; the trajectory keeps equal
//! axes. Skipped with a message when `../shared/data` is absent.
#![cfg(not(target_arch = "wasm32"))]

mod common;

use common::shared_data;
use compass_pdr::pdr::PdrOptions;
use compass_pdr::pipeline;
use compass_pdr::present::plot::pdr::draw_trajectory;
use compass_pdr::present::plot::zoom::{PlotFrame, Zoom};
use compass_pdr::present::plot::{draw_field_magnitude_of, draw_heading_error};
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

/// The live panel's 3D view on real boards, their recorded field replayed as a board
/// prints it (Adafruit `Uni:` lines, µT): the HMC5883L turned over the whole sphere
/// leaves hardly a region shaded; the same board turned about its z axis only leaves
/// most of the sphere shaded.
#[test]
fn the_3d_view_of_real_boards_shades_what_they_never_pointed_at() {
    use compass_pdr::live::LiveSession;
    use compass_pdr::present::plot::sphere_view::{draw_sphere_view, SphereView};
    let Some(data) = shared_data() else { return };
    let mut shaded = Vec::new();
    for folder in ["full-sphere", "rotate-ccw-around-z-pointing-up"] {
        let dir = data.join("hmc5883l-sphere").join(folder);
        let import = common::import_paths(&[dir.join("hmc5883l_compass.csv")]);
        let mut text = String::new();
        for field in &import.recording.mag_in_body_ut.values {
            text.push_str(&format!(
                "Uni:0,0,9.81,0,0,0,{:.3},{:.3},{:.3}\n",
                field.x, field.y, field.z
            ));
        }
        let mut session = LiveSession::new();
        session.feed(text.as_bytes(), 0.0);
        let quality = session.refit().expect("a fit").clone();
        let mut svg = String::new();
        {
            let area = SVGBackend::with_string(&mut svg, (600, 600)).into_drawing_area();
            draw_sphere_view(
                &area,
                session.kept_samples_ut(),
                Some(&quality),
                SphereView::default(),
            )
            .expect("drawn");
        }
        let n_shaded = svg.matches("fill=\"#C83C28\"").count();
        // The latest sample's ring: where the board points now.
        assert_eq!(svg.matches("stroke=\"#009646\"").count(), 1, "{folder}");
        eprintln!(
            "{folder}: {} of 100 regions covered, {n_shaded} shaded on the near side",
            quality.coverage.n_covered
        );
        shaded.push((quality.coverage.n_covered, n_shaded));
    }
    let [(full_covered, full_shaded), (turn_covered, turn_shaded)] = shaded[..] else {
        panic!("two boards");
    };
    assert!(full_covered >= 90 && full_shaded <= 5, "{shaded:?}");
    assert!(turn_covered <= 40 && turn_shaded >= 20, "{shaded:?}");
}

/// Issue 45: an autopilot log's picture, each compass against the Earth's field in force
/// and as written, says every bar's figure in words (readable without colour), and they
/// are the figures of the compasses' sentences.
#[test]
fn an_autopilot_log_s_compasses_are_drawn_with_their_figures() {
    let Some(data) = shared_data() else { return };
    let import = common::import_paths(&[data.join("ardupilot-copter-log171/log171.bin")]);
    let mut options = PdrOptions::default();
    options.heading_options.neural = false;
    let analysis = pipeline::analyse(&import, &options).expect("analyses");
    let autopilot = analysis
        .calibration
        .report
        .autopilot
        .as_ref()
        .expect("the compasses were assessed");
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (560, 314)).into_drawing_area();
        compass_pdr::present::plot::compass_errors::draw_compass_errors(&root, autopilot)
            .expect("drawn");
    }
    for compass in &autopilot.compasses {
        assert!(
            svg.contains(&compass.label()),
            "{} is named",
            compass.label()
        );
        if let Some(in_force) = compass.whole.in_force {
            let text = format!("in force: {:.0}", in_force.vector_rms_mg);
            assert!(svg.contains(&text), "{text} is written");
        }
        if let Some(new) = compass.whole.new {
            let what = if compass.is_written() {
                "written"
            } else {
                "fitted, kept out"
            };
            let text = format!("{what}: {:.0}", new.vector_rms_mg);
            assert!(svg.contains(&text), "{text} is written");
        }
    }
}
