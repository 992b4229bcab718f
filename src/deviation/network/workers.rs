//! The parts of a large batch evaluated beside the caller's thread, on the crate's
//! helper threads ([`crate::base::par::Helpers`]; native builds, wasm runs every part on its
//! one thread).
//!
//! L-BFGS evaluates the objective a few hundred times in a row, each evaluation taking
//! a fraction of a millisecond, so a batch starts its helpers once, at its first large
//! evaluation, and keeps them until it is dropped. Each helper owns its scratch space,
//! receives a job (the parameters and a run of whole parts), and sends the job back
//! with the parts' sums.
//!
//! The parts, and so the bits of the result, do not depend on how many helpers run: the
//! caller adds the parts' sums in the order of the parts.

use std::ops::Range;
use std::sync::Arc;

use crate::base::par::Helpers;

use super::activation::Activation;
use super::kernels::{self, PartInput, Scratch};
use super::loss::{Samples, Shape};

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

/// The helper threads of one batch (none until the first large evaluation).
pub(crate) struct Workers {
    shape: Shape,
    activation: Activation,
    helpers: Helpers<Job>,
    /// The buffers of each helper's last job, reused by its next.
    spare: Vec<Option<Job>>,
}

impl Workers {
    pub fn new(shape: Shape, activation: Activation) -> Self {
        Workers {
            shape,
            activation,
            helpers: Helpers::default(),
            spare: Vec::new(),
        }
    }

    /// Starts helpers until there are `n_helpers` (fewer if the system refuses a
    /// thread) and returns how many there are.
    fn ensure(&mut self, n_helpers: usize) -> usize {
        let (shape, activation) = (self.shape, self.activation);
        let n = self.helpers.ensure(n_helpers, "nn-batch", || {
            let mut scratch = Scratch::new(shape);
            move |job| help(shape, activation, &mut scratch, job)
        });
        if self.spare.len() < n {
            self.spare.resize_with(n, || None);
        }
        n
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
        let sent: Vec<bool> = (0..n_threads - 1)
            .map(|helper_idx| {
                let mut job = self.spare[helper_idx].take().unwrap_or_else(|| Job {
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
                self.helpers.send(helper_idx, job).is_ok()
            })
            .collect();

        let input = PartInput {
            shape: self.shape,
            activation: self.activation,
            params,
            inputs: &samples.inputs,
            targets: &samples.targets,
            stride: samples.stride,
        };
        run(&input, span_of(0), part_len, scratch, part_sums, sums_len);

        for (helper_idx, &sent) in sent.iter().enumerate() {
            let span = span_of(helper_idx + 1);
            let first = first_part_of(helper_idx + 1) * sums_len;
            let last = first_part_of(helper_idx + 2) * sums_len;
            let mine = &mut part_sums[first..last];
            match sent.then(|| self.helpers.receive(helper_idx)).flatten() {
                Some(mut job) => {
                    mine.copy_from_slice(&job.sums[..mine.len()]);
                    job.samples = None;
                    self.spare[helper_idx] = Some(job);
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

/// A helper's job: the parts of its span evaluated into its sums.
fn help(shape: Shape, activation: Activation, scratch: &mut Scratch, mut job: Job) -> Job {
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
            scratch,
            &mut job.sums,
            job.sums_len,
        );
    }
    job
}
