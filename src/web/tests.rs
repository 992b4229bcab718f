//! Browser tests of the web edge (wasm-bindgen-test in headless Chromium).

use wasm_bindgen::JsCast;
use wasm_bindgen_test::*;
use web_sys::{CanvasRenderingContext2d, HtmlCanvasElement};

use super::canvas::{self, Plot};
use crate::analysis::calibration::{CalibrationOptions, Method};
use crate::io::canonical_csv;
use crate::pipeline::calibrate_file as analyse_log;
use crate::sim::walk::{simulate, WalkConfig};

wasm_bindgen_test_configure!(run_in_browser);

fn simulated_csv() -> Vec<u8> {
    canonical_csv::write(&simulate(&WalkConfig::from_seed(2, 120.0))).into_bytes()
}

fn new_canvas(width_px: u32, height_px: u32) -> HtmlCanvasElement {
    let document = web_sys::window()
        .and_then(|window| window.document())
        .expect("a document");
    let canvas: HtmlCanvasElement = document
        .create_element("canvas")
        .expect("canvas")
        .dyn_into()
        .expect("a canvas");
    canvas.set_width(width_px);
    canvas.set_height(height_px);
    document
        .body()
        .expect("a body")
        .append_child(&canvas)
        .expect("appended");
    canvas
}

/// Pixels that are not the white background.
fn n_drawn_pixels(canvas: &HtmlCanvasElement) -> usize {
    let context: CanvasRenderingContext2d = canvas
        .get_context("2d")
        .expect("context")
        .expect("2d")
        .dyn_into()
        .expect("a 2D context");
    let data = context
        .get_image_data(0, 0, canvas.width() as i32, canvas.height() as i32)
        .expect("pixels")
        .data();
    data.chunks_exact(4)
        .filter(|rgba| rgba[0] < 250 || rgba[1] < 250 || rgba[2] < 250)
        .count()
}

#[wasm_bindgen_test]
fn analyse_file_returns_the_summary_as_a_plain_object() {
    let value = super::analyse_file("walk.csv", &simulated_csv())
        .map_err(wasm_bindgen::JsValue::from)
        .expect("analysable");
    let rms = js_sys::Reflect::get(&value, &"methods".into())
        .and_then(|methods| js_sys::Reflect::get(&methods, &0u32.into()))
        .and_then(|min_max| js_sys::Reflect::get(&min_max, &"heading_error_check".into()))
        .and_then(|check| js_sys::Reflect::get(&check, &"rms_deg".into()))
        .ok()
        .and_then(|rms| rms.as_f64())
        .expect("methods[0].heading_error_check.rms_deg is a number");
    assert!(rms > 0.0 && rms < 3.0, "{rms}");
    let file_name = js_sys::Reflect::get(&value, &"file_name".into())
        .ok()
        .and_then(|name| name.as_string());
    assert_eq!(file_name.as_deref(), Some("walk.csv"));
}

#[wasm_bindgen_test]
fn analyse_file_throws_a_message_that_names_the_file() {
    let garbage: Vec<u8> = (0..2000u32)
        .map(|idx| (idx.wrapping_mul(2_654_435_761) >> 7) as u8)
        .collect();
    let error = super::analyse_file("noise.bin", &garbage)
        .map_err(wasm_bindgen::JsValue::from)
        .expect_err("garbage is refused");
    let message: String = error
        .dyn_into::<js_sys::Error>()
        .expect("an Error")
        .message()
        .into();
    assert!(message.contains("noise.bin is not a text log"), "{message}");
}

#[wasm_bindgen_test]
fn both_plots_draw_on_a_canvas() {
    let analysis = analyse_log("walk.csv", &simulated_csv(), &CalibrationOptions::default())
        .expect("analysable");
    for plot in [Plot::CircleFit, Plot::HeadingError, Plot::FieldMagnitude] {
        let canvas = new_canvas(480, 360);
        canvas::draw(
            &canvas,
            plot,
            &analysis,
            crate::present::plot::zoom::Zoom::WHOLE,
        )
        .expect("drawn");
        let n_drawn = n_drawn_pixels(&canvas);
        assert!(n_drawn > 5_000, "{plot:?}: only {n_drawn} pixels drawn");
    }
}

#[wasm_bindgen_test]
fn an_error_message_replaces_the_plot() {
    let canvas = new_canvas(480, 360);
    canvas::draw_message(
        &canvas,
        "noise.bin is not a text log (binary data near byte 0).",
    )
    .expect("drawn");
    assert!(
        n_drawn_pixels(&canvas) > 10_000,
        "the message panel is drawn"
    );
}

/// The elements `www/index.html` gives the page, enough for [`super::page::Page`].
fn add_page_skeleton() {
    let document = web_sys::window()
        .and_then(|window| window.document())
        .expect("a document");
    let skeleton = document.create_element("div").expect("div");
    skeleton.set_inner_html(
        r#"<div id="drop-zone"><input id="file-input" type="file"></div><p id="status"></p>
           <span id="result-file"></span><ul id="context"></ul><table><tbody id="methods-body"></tbody></table>
           <ul id="calibration"></ul><ul id="notes"></ul><ul id="diagnostics"></ul>
           <canvas id="plot-circle" width="320" height="240"></canvas><canvas id="plot-heading" width="320" height="240"></canvas>
           <canvas id="plot-field" width="320" height="240"></canvas><ul id="deviation-model"></ul>
           <canvas id="plot-deviation" width="320" height="240"></canvas><canvas id="plot-residuals" width="320" height="240"></canvas><canvas id="plot-online" width="320" height="240"></canvas>
           <ul id="pdr-summary"></ul><canvas id="plot-trajectory" width="320" height="240"></canvas>
           <canvas id="plot-steps" width="320" height="240"></canvas><canvas id="plot-position-error" width="320" height="240"></canvas>
           <section id="summary"><p id="verdict-grade"></p><h2 id="verdict-headline"></h2><p id="verdict-method"></p>
           <dl id="verdict-figures"></dl><ul id="verdict-to-do"></ul><p id="verdict-read"></p></section>"#,
    );
    document
        .body()
        .expect("a body")
        .append_child(&skeleton)
        .expect("appended");
}

#[wasm_bindgen_test]
fn the_page_shows_an_analysis_then_an_error() {
    add_page_skeleton();
    let page = super::page::Page::from_document(None).expect("the skeleton has every element");
    let document = web_sys::window()
        .and_then(|window| window.document())
        .expect("a document");
    let text = |id: &str| {
        document
            .get_element_by_id(id)
            .and_then(|element| element.text_content())
            .unwrap_or_default()
    };

    // The page's own steps, as its analysis worker runs them.
    let import = std::sync::Arc::new(
        crate::io::import::import("walk.csv", &simulated_csv()).expect("readable"),
    );
    let results = super::page::analysis::Steps::new(super::page::analysis::Request {
        import: std::sync::Arc::clone(&import),
        stage: crate::pipeline::Stage::Calibration,
        previous: None,
        options: crate::pdr::PdrOptions::default(),
    })
    .finish()
    .expect("analysable");
    page.show_analysis(&results, Some(&import));
    let min_max = results
        .calibration
        .report
        .method(Method::MinMax)
        .expect("min/max ran");
    let check = min_max.heading_error_check.expect("reference present");
    assert_eq!(
        text("stat-min_max-check-rms"),
        format!("{:.2}°", check.rms_deg)
    );
    assert_eq!(text("result-file"), "walk.csv");
    assert_eq!(text("diagnostics"), "None.");
    // The heading models stand on the calibration: a Fourier stack per method.
    assert!(text("stat-min_max-fourier-check-rms").ends_with('°'));
    assert!(text("deviation-model").contains("min/max: A "));
    assert!(text("status").starts_with("Analysed walk.csv"));
    // The walk is dead-reckoned too: its steps, and the error against its positions.
    assert!(
        text("pdr-summary").contains(" steps in "),
        "{}",
        text("pdr-summary")
    );
    assert!(text("pdr-summary").contains("Position error at "));
    assert!(
        text("status").contains("steps dead-reckoned"),
        "{}",
        text("status")
    );
    // The answer first: the summary names the method and the heading error before and
    // after, and it is emptied with the rest on an error.
    assert!(
        text("verdict-headline").starts_with("Heading error "),
        "{}",
        text("verdict-headline")
    );
    assert!(
        text("verdict-method").starts_with("Method: "),
        "{}",
        text("verdict-method")
    );
    assert!(
        text("verdict-figures").contains("Dead reckoning"),
        "{}",
        text("verdict-figures")
    );

    page.show_error("bad.csv is empty. Choose a log with a header line and samples.");
    let body = document.body().expect("a body");
    assert_eq!(body.get_attribute("data-state").as_deref(), Some("error"));
    assert_eq!(text("methods-body"), "", "the table is emptied");
    assert_eq!(text("verdict-figures"), "", "the summary is emptied");
    assert_eq!(
        text("status"),
        "bad.csv is empty. Choose a log with a header line and samples."
    );
    // Text from a log is inserted as text: markup in a file name stays visible text.
    page.show_error("<b>x</b>.csv is empty.");
    assert_eq!(text("status"), "<b>x</b>.csv is empty.");
}

#[wasm_bindgen_test]
fn a_stored_entry_reads_back_and_a_corrupt_one_is_set_aside_with_a_notice() {
    use super::storage::{self, Settings};
    let window = web_sys::window().expect("a window");
    let document = window.document().expect("a document");
    let storage_area = window
        .local_storage()
        .expect("storage")
        .expect("local storage");
    let notice = document.create_element("p").expect("p");
    notice.set_id("storage-notice");
    document
        .body()
        .expect("a body")
        .append_child(&notice)
        .expect("appended");
    let key = "compass-pdr.test-settings.v1";
    let settings = Settings {
        baud_rate: Some(57_600),
        lat_deg: Some(48.14),
        lon_deg: None,
    };
    storage::save(key, &settings);
    assert_eq!(
        storage::load::<Settings>(key, "test settings"),
        Some(settings)
    );
    assert_eq!(notice.text_content().unwrap_or_default(), "");

    storage_area
        .set_item(key, "{\"baud_rate\": \"fast\"}")
        .expect("stored");
    assert_eq!(storage::load::<Settings>(key, "test settings"), None);
    let text = notice.text_content().unwrap_or_default();
    assert!(
        text.starts_with("The saved test settings could not be read ("),
        "{text}"
    );
    assert_eq!(storage_area.get_item(key).expect("read"), None, "set aside");
    // Nothing stored: nothing said.
    notice.set_text_content(None);
    assert_eq!(storage::load::<Settings>(key, "test settings"), None);
    assert_eq!(notice.text_content().unwrap_or_default(), "");
}

#[wasm_bindgen_test]
fn plots_are_drawn_at_the_device_pixel_ratio_and_laid_out_in_css_pixels() {
    let canvas = new_canvas(300, 200);
    let ratio = web_sys::window()
        .expect("a window")
        .device_pixel_ratio()
        .clamp(1.0, 4.0);
    canvas::draw_message(&canvas, "a message").expect("drawn");
    assert_eq!(canvas::logical_size(&canvas), (300, 200));
    assert_eq!(canvas.width(), (300.0 * ratio).round() as u32);
    // Drawing again keeps the layout size (not the enlarged backing store).
    canvas::draw_message(&canvas, "again").expect("drawn");
    assert_eq!(canvas.width(), (300.0 * ratio).round() as u32);
    assert!(n_drawn_pixels(&canvas) > 100);
}

#[wasm_bindgen_test]
fn the_attitude_download_says_which_sensors_a_log_lacks() {
    use crate::io::recording::{Recording, Stream};
    let walk = crate::io::import::import("walk.csv", &simulated_csv()).expect("readable");
    assert_eq!(super::exports::attitude_missing(&walk.recording), None);
    let compass_only = Recording {
        mag_in_body_ut: walk.recording.mag_in_body_ut.clone(),
        ..Recording::default()
    };
    assert_eq!(
        super::exports::attitude_missing(&compass_only).as_deref(),
        Some(
            "The attitude filter needs a gyroscope and an accelerometer; this log has no \
             gyroscope and no accelerometer."
        )
    );
    let mut no_gyro = walk.recording;
    no_gyro.gyro_in_body_radps = Stream::default();
    assert!(super::exports::attitude_missing(&no_gyro)
        .is_some_and(|message| message.ends_with("this log has no gyroscope.")));
}
