//! Helper threads kept for a run of many small jobs (native builds): where
//! [`super::on_each_part`] starts its threads for each piece of work, a run of hundreds
//! of sub-millisecond evaluations (an optimiser's objective) would pay about as much for
//! the starts as it saves, so [`Helpers`] starts its threads once and keeps them until
//! it is dropped. Each helper owns the state its handler was made with, receives a job
//! over a channel and sends it back done. Waiting first spins briefly (consecutive
//! jobs follow each other within microseconds, and waking a parked thread can take far
//! longer), then yields, then blocks.
//!
//! Native builds only: in WebAssembly the callers run every job on their own thread.

use std::sync::mpsc::{self, Receiver, Sender, TryRecvError};

/// How many rounds of 64 polls a waiting thread spins (a round is a microsecond or two
/// of polling, so some 20 µs), then how many more it yields between rounds (some
/// 200 µs), before it blocks. Counted, not timed: the core reads no clock.
const SPIN_ROUNDS: u32 = 16;
const YIELD_ROUNDS: u32 = 160;

/// One helper thread and its channels.
struct Helper<J> {
    jobs: Option<Sender<J>>,
    done: Receiver<J>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl<J> Drop for Helper<J> {
    fn drop(&mut self) {
        // Closing the channel ends the helper's loop.
        self.jobs = None;
        if let Some(thread) = self.thread.take() {
            // A helper that panicked has nothing left to clean up.
            let _ = thread.join();
        }
    }
}

/// Helper threads that each turn a job `J` into a done `J`.
pub struct Helpers<J> {
    helpers: Vec<Helper<J>>,
}

impl<J: Send + 'static> Default for Helpers<J> {
    fn default() -> Self {
        Helpers {
            helpers: Vec::new(),
        }
    }
}

impl<J: Send + 'static> Helpers<J> {
    /// Starts helpers, each running a handler `make` gives, until there are `n` (fewer
    /// if the system refuses a thread); returns how many of the first `n` there are.
    pub fn ensure<H>(&mut self, n: usize, name: &str, make: impl Fn() -> H) -> usize
    where
        H: FnMut(J) -> J + Send + 'static,
    {
        while self.helpers.len() < n {
            let (jobs, job_receiver) = mpsc::channel::<J>();
            let (done_sender, done) = mpsc::channel::<J>();
            let mut handler = make();
            let spawned = std::thread::Builder::new()
                .name(name.to_owned())
                .spawn(move || {
                    while let Some(job) = receive(&job_receiver) {
                        if done_sender.send(handler(job)).is_err() {
                            return;
                        }
                    }
                });
            let Ok(thread) = spawned else { break };
            self.helpers.push(Helper {
                jobs: Some(jobs),
                done,
                thread: Some(thread),
            });
        }
        self.helpers.len().min(n)
    }

    /// Hands `job` to helper `idx`; gives it back when that helper is gone.
    pub fn send(&self, idx: usize, job: J) -> Result<(), J> {
        match self
            .helpers
            .get(idx)
            .and_then(|helper| helper.jobs.as_ref())
        {
            Some(jobs) => jobs.send(job).map_err(|error| error.0),
            None => Err(job),
        }
    }

    /// The job helper `idx` finished; `None` when it is gone.
    pub fn receive(&self, idx: usize) -> Option<J> {
        receive(&self.helpers.get(idx)?.done)
    }
}

/// The next message, spinning for [`SPIN_ROUNDS`] and then yielding to other threads
/// for [`YIELD_ROUNDS`] before blocking (a busy machine gets its core back); `None` when
/// the other side has gone.
fn receive<T>(channel: &Receiver<T>) -> Option<T> {
    for round in 0..SPIN_ROUNDS + YIELD_ROUNDS {
        for _ in 0..64 {
            match channel.try_recv() {
                Ok(message) => return Some(message),
                Err(TryRecvError::Disconnected) => return None,
                Err(TryRecvError::Empty) => std::hint::spin_loop(),
            }
        }
        if round >= SPIN_ROUNDS {
            std::thread::yield_now();
        }
    }
    channel.recv().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_helper_keeps_its_state_across_jobs() {
        let mut helpers: Helpers<(usize, u64)> = Helpers::default();
        let n = helpers.ensure(3, "test", || {
            let mut count = 0_u64;
            move |(idx, _): (usize, u64)| {
                count += 1;
                (idx, count)
            }
        });
        assert_eq!(n, 3);
        for round in 1..=4_u64 {
            for idx in 0..n {
                assert!(helpers.send(idx, (idx, 0)).is_ok());
            }
            for idx in 0..n {
                assert_eq!(helpers.receive(idx), Some((idx, round)));
            }
        }
        assert!(helpers.send(7, (7, 0)).is_err(), "no such helper");
    }
}
