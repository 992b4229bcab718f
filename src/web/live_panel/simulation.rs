//! The simulated board: the simulator's calibration dance played into the session on a
//! timer, as a board's port would deliver it, so that the panel can be tried without a
//! board (and without Web Serial); its true hard iron is said at the end.

use std::rc::Rc;

use super::{every, now_ms, LivePanel};
use crate::sim::dance::{motioncal_raw_lines, DanceConfig, DanceTruth};

/// How long the simulated board's dance is (s of the board's time).
const SIMULATED_DANCE_S: f64 = 60.0;
/// How much faster than the board the simulated dance plays.
const SIMULATION_SPEED_UP: f64 = 10.0;
/// How often the simulated board delivers a piece (ms).
const SIMULATION_TICK_MS: f64 = 50.0;

/// A simulated board's text, how much of it was delivered, and its truth.
pub(super) struct Simulation {
    text: Vec<u8>,
    sent: usize,
    /// Lines sent so far, and the board's lines per second: the board's clock.
    lines_sent: usize,
    rate_hz: f64,
    bytes_per_tick: usize,
    truth: DanceTruth,
}

impl LivePanel {
    /// Plays the simulator's calibration dance (`sim::dance`: MotionCal `Raw:` lines of
    /// a board with a random hard and soft iron) into the session as a board's port
    /// would deliver it, ten times as fast as the board would, in pieces cut anywhere,
    /// so that the panel can be tried without a board. The truth is said at the end.
    pub(super) fn start_simulation(self: &Rc<Self>) {
        if self.reading.get() {
            return;
        }
        let seed = (now_ms() as u64) % 1000 + 1;
        let config = DanceConfig::from_seed(seed, SIMULATED_DANCE_S);
        let (text, truth) = motioncal_raw_lines(&config);
        let bytes_per_tick = (text.len() as f64 / SIMULATED_DANCE_S
            * SIMULATION_SPEED_UP
            * SIMULATION_TICK_MS
            / 1e3)
            .ceil() as usize;
        self.update_expected_field();
        self.reading.set(true);
        self.update_buttons();
        self.set_state(
            "connected",
            &format!(
                "A simulated board (seed {seed}) is turned through every direction, printing \
                 MotionCal Raw: lines; it plays ten times as fast as a board would."
            ),
        );
        self.start_ticker();
        let panel = Rc::clone(self);
        let Some(ticker) = every(SIMULATION_TICK_MS, move || panel.play_simulation()) else {
            self.reading.set(false);
            self.stop_ticker();
            self.update_buttons();
            return;
        };
        *self.simulation.borrow_mut() = Some((
            ticker,
            Simulation {
                text: text.into_bytes(),
                sent: 0,
                lines_sent: 0,
                rate_hz: config.rate_hz,
                bytes_per_tick: bytes_per_tick.max(1),
                truth,
            },
        ));
    }

    /// The simulated board's next piece; at the end of its text, the end of the session.
    fn play_simulation(&self) {
        let piece = {
            let mut simulation = self.simulation.borrow_mut();
            let Some((_, playing)) = simulation.as_mut() else {
                return;
            };
            let start = playing.sent;
            let end = (start + playing.bytes_per_tick).min(playing.text.len());
            playing.sent = end;
            // On the board's clock (the lines printed so far at its rate), not the page's,
            // which runs ten times slower, nor the share of bytes sent (lines differ in
            // length, and that clock drifted by seconds over the dance): the attitude
            // filter integrates the gyroscope over these times.
            let piece_lines = playing.text[start..end]
                .iter()
                .filter(|&&byte| byte == b'\n')
                .count();
            playing.lines_sent += piece_lines;
            let board_t_s = playing.lines_sent as f64 / playing.rate_hz;
            playing
                .text
                .get(start..end)
                .map(|piece| (piece.to_vec(), board_t_s))
        };
        match piece {
            Some((piece, board_t_s)) if !piece.is_empty() => {
                self.session.borrow_mut().feed(&piece, board_t_s);
                self.dirty.set(true);
            }
            _ => self.stop_simulation(),
        }
    }

    /// Ends the simulated board (at the end of its text, or on Disconnect).
    pub(super) fn stop_simulation(&self) {
        let Some(((id, _tick), simulation)) = self.simulation.borrow_mut().take() else {
            return;
        };
        if let Some(window) = web_sys::window() {
            window.clear_interval_with_handle(id);
        }
        self.stop_ticker();
        self.reading.set(false);
        self.session.borrow_mut().port_closed();
        self.refit_and_draw();
        let n_lines = self.session.borrow().counts().n_lines;
        let [x, y, z] = simulation.truth.hard_iron_ut;
        self.set_state(
            "disconnected",
            &format!(
                "The simulated board stopped after {n_lines} lines. Its true hard iron was \
                 ({x:.2}, {y:.2}, {z:.2}) µT: compare the fit. Download the recording, or connect \
                 a real board."
            ),
        );
        self.update_buttons();
    }
}
