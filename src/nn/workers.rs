//! Helper threads that evaluate parts of a large batch beside the caller's thread
//! (native builds; wasm runs every part on its one thread).
//!
//! L-BFGS evaluates the objective a few hundred times in a row, each evaluation taking
//! a fraction of a millisecond, so starting threads for each one would cost about as
//! much as it saves. A batch therefore starts its helpers once, at its first large
//! evaluation, and keeps them until it is dropped. Each helper owns its scratch space,
//! receives a job (the parameters and a run of whole parts) over a channel, and sends the
//! job back with the parts' sums. Waiting for a job or a result first spins briefly
//! (consecutive evaluations follow each other within microseconds, and waking a parked
//! thread can take far longer) and then blocks.
//!
//! The parts, and so the bits of the result, do not depend on how many helpers run: the
//! caller adds the parts' sums in the order of the parts.

use std::ops::Range;
use std::sync::mpsc::{self, Receiver, Sender, TryRecvError};
use std::sync::Arc;

use super::activation::Activation;
use super::kernels::{self, PartInput, Scratch};
use super::loss::{Samples, Shape};

/// How many rounds of 64 polls a waiting thread spins (a round is a microsecond or two
/// of polling, so some 20 µs), then how many more it yields between rounds (some
/// 200 µs), before it blocks. Counted, not timed: the core reads no clock.
const SPIN_ROUNDS: u32 = 16;
const YIELD_ROUNDS: u32 = 160;

/// What a helper evaluates, and where it writes.
struct Job {
    samples: Option<Arc<Samples>>,
    /// The weights rounded to the kernels' `f32`.
    params: Vec<f32>,
    /// The whole parts of `part_len` samples to evaluate (the last may be shorter).
    span: Range<usize>,
    part_len: usize,
    /// Sums per part (`n_outputs`, plus `n_params` with the gradient).
    sums_len: usize,
    sums: Vec<f64>,
}

/// One helper thread and its channels.
struct Helper {
    jobs: Option<Sender<Job>>,
    done: Receiver<Job>,
    /// The buffers of the last job, reused by the next.
    spare: Option<Job>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Helper {
    fn drop(&mut self) {
        // Closing the channel ends the helper's loop.
        self.jobs = None;
        if let Some(thread) = self.thread.take() {
            // A helper that panicked has nothing left to clean up.
            let _ = thread.join();
        }
    }
}

/// The helper threads of one batch (none until the first large evaluation).
pub(crate) struct Workers {
    shape: Shape,
    activation: Activation,
    helpers: Vec<Helper>,
}

impl Workers {
    pub fn new(shape: Shape, activation: Activation) -> Self {
        Workers {
            shape,
            activation,
            helpers: Vec::new(),
        }
    }

    /// Starts helpers until there are `n_helpers` (fewer if the system refuses a
    /// thread) and returns how many there are.
    fn ensure(&mut self, n_helpers: usize) -> usize {
        while self.helpers.len() < n_helpers {
            let (jobs, job_receiver) = mpsc::channel::<Job>();
            let (done_sender, done) = mpsc::channel::<Job>();
            let (shape, activation) = (self.shape, self.activation);
            let spawned = std::thread::Builder::new()
                .name("nn-batch".to_owned())
                .spawn(move || help(shape, activation, &job_receiver, &done_sender));
            let Ok(thread) = spawned else { break };
            self.helpers.push(Helper {
                jobs: Some(jobs),
                done,
                spare: None,
                thread: Some(thread),
            });
        }
        self.helpers.len().min(n_helpers)
    }

    /// Evaluates the parts of `range` (`part_len` samples each) into `part_sums`
    /// (`sums_len` per part) on this thread and up to `n_threads − 1` helpers, each
    /// taking a contiguous run of parts.
    #[allow(clippy::too_many_arguments)]
    pub fn evaluate(
        &mut self,
        samples: &Arc<Samples>,
        params: &[f32],
        range: Range<usize>,
        part_len: usize,
        n_threads: usize,
        scratch: &mut Scratch,
        part_sums: &mut [f64],
        sums_len: usize,
    ) {
        let n_parts = range.len().div_ceil(part_len);
        let n_threads = 1 + self.ensure(n_threads.min(n_parts).saturating_sub(1));
        let first_part_of = |thread_idx: usize| n_parts * thread_idx / n_threads;
        let span_of = |thread_idx: usize| {
            let start = range.start + first_part_of(thread_idx) * part_len;
            let end = (range.start + first_part_of(thread_idx + 1) * part_len).min(range.end);
            start..end
        };
        let mut sent = vec![false; n_threads - 1];
        for (helper_idx, helper) in self.helpers[..n_threads - 1].iter_mut().enumerate() {
            let mut job = helper.spare.take().unwrap_or_else(|| Job {
                samples: None,
                params: Vec::new(),
                span: 0..0,
                part_len,
                sums_len,
                sums: Vec::new(),
            });
            job.samples = Some(Arc::clone(samples));
            job.params.clear();
            job.params.extend_from_slice(params);
            job.span = span_of(helper_idx + 1);
            job.part_len = part_len;
            job.sums_len = sums_len;
            if let Some(jobs) = &helper.jobs {
                sent[helper_idx] = jobs.send(job).is_ok();
            }
        }

        let input = PartInput {
            shape: self.shape,
            activation: self.activation,
            params,
            inputs: &samples.inputs,
            targets: &samples.targets,
            stride: samples.stride,
        };
        run(&input, span_of(0), part_len, scratch, part_sums, sums_len);

        for (helper_idx, helper) in self.helpers[..n_threads - 1].iter_mut().enumerate() {
            let span = span_of(helper_idx + 1);
            let first = first_part_of(helper_idx + 1) * sums_len;
            let last = first_part_of(helper_idx + 2) * sums_len;
            let mine = &mut part_sums[first..last];
            match sent[helper_idx].then(|| receive(&helper.done)).flatten() {
                Some(mut job) => {
                    mine.copy_from_slice(&job.sums[..mine.len()]);
                    job.samples = None;
                    helper.spare = Some(job);
                }
                // The helper is gone (it cannot be, short of a bug): do its share here.
                None => run(&input, span, part_len, scratch, mine, sums_len),
            }
        }
    }
}

/// Evaluates the parts of `span` into consecutive `sums_len` runs of `part_sums`.
fn run(
    input: &PartInput,
    span: Range<usize>,
    part_len: usize,
    scratch: &mut Scratch,
    part_sums: &mut [f64],
    sums_len: usize,
) {
    let mut start = span.start;
    for sums in part_sums.chunks_exact_mut(sums_len) {
        if start >= span.end {
            break;
        }
        let end = (start + part_len).min(span.end);
        kernels::evaluate_part(input, start..end, scratch, sums);
        start = end;
    }
}

/// A helper's loop: jobs in, results out, until the batch closes the channel.
fn help(shape: Shape, activation: Activation, jobs: &Receiver<Job>, done: &Sender<Job>) {
    let mut scratch = Scratch::new(shape);
    while let Some(mut job) = receive(jobs) {
        if let Some(samples) = job.samples.take() {
            let n_parts = job.span.len().div_ceil(job.part_len);
            job.sums.resize(n_parts * job.sums_len, 0.0);
            let input = PartInput {
                shape,
                activation,
                params: &job.params,
                inputs: &samples.inputs,
                targets: &samples.targets,
                stride: samples.stride,
            };
            run(
                &input,
                job.span.clone(),
                job.part_len,
                &mut scratch,
                &mut job.sums,
                job.sums_len,
            );
        }
        if done.send(job).is_err() {
            return;
        }
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
