//! The inner loops of a batch evaluation: the forward pass, the residuals and the
//! gradient of one *part* of the samples, eight samples at a time, in single precision.
//!
//! **Precision.** The samples, the weights of the evaluation, the activations and the
//! residuals are `f32`, as in the usual neural-network libraries: the targets are
//! normalised, so single precision resolves a residual to about 10⁻⁷ of the target's
//! spread, far below any heading error worth modelling. Sums are formed in `f32` lanes
//! over one chunk of [`CHUNK`] samples and then added in `f64`, and the optimiser keeps
//! its weights, gradients and curvature pairs in `f64`. Eight `f32` lanes fill an AVX2
//! register (four `f64` did), so an evaluation does half the instructions.
//!
//! The kernel is written once, generic over [`Lanes`] (eight `f32` lanes with the few
//! operations it needs), and compiled for three kinds of lanes: [`Portable`]
//! (`[f32; 8]`, plain scalar operations, the reference), WebAssembly's 128-bit SIMD
//! (`kernels/simd128.rs`, two `f32x4` registers: what both of the page's modules run)
//! and, on x86-64 when the processor has AVX2 (checked at run time), `Avx2` (one
//! 256-bit register). Each lane does exactly the portable code's IEEE operations in the
//! same order (no fused multiply-add, which wasm lacks), and the reduction of the lanes
//! is the same scalar code, so all give the same bits: a network trained natively and in
//! the browser is the same network. A test checks it, natively and in the browser.
//!
//! The page's modules are built for size (`scripts/setup.sh`), under which the compiler
//! neither vectorises nor unrolls loops by itself, so the lanes are explicit and the
//! loops over a group of inputs, whose accumulators must stay in registers, are unrolled
//! by a macro for each group size.
//!
//! Order of the sums (which fixes the bits): per chunk, each accumulated quantity has
//! eight `f32` lane sums starting at zero; lane `l` adds the chunk's samples
//! `chunk_start + 8v + l` for `v = 0, 1, …` in order. At the end of the chunk the lanes
//! are converted to `f64` and reduced as `((l₀ + l₁) + (l₂ + l₃)) + ((l₄ + l₅) + (l₆ + l₇))`,
//! and that is added to the part's `f64` sum, chunk after chunk. Samples past the end of
//! the range (the last vector's spare lanes) get a residual of exactly `+0`, so they add
//! `±0` to every sum.

use super::activation::{Activation, EXP_COEFFICIENTS, EXP_LIMIT, LN2_HI, LN2_LO, ROUND};
use super::loss::Shape;

/// Lanes per vector.
pub(crate) const LANES: usize = 8;

/// Samples in a [`Pair`] of vectors.
pub(crate) const PAIR: usize = 2 * LANES;

/// Samples per chunk: the chunk's hidden activations (16 × 128 × 4 bytes = 8 KiB) stay
/// in the L1 cache between the forward and the backward pass. A multiple of [`PAIR`].
pub(crate) const CHUNK: usize = 128;

/// The most inputs whose weight-gradient accumulators are kept in registers at once
/// (with the neuron's bias and output-weight accumulators and the temporaries, this
/// fills AVX2's 16 registers).
const MAX_GROUP: usize = 6;

/// Eight `f32` lanes. Every operation acts lane by lane with IEEE single rounding, except
/// where said; `min` and `max` follow x86's `minps`/`maxps` (the second operand when
/// either is NaN).
pub(crate) trait Lanes: Copy {
    /// Samples per value (8, or 16 for a [`Pair`]).
    const WIDTH: usize;
    /// The most inputs one backward pass keeps accumulators for: as many as the
    /// registers hold. The grouping does not change any sum, only how many passes there
    /// are.
    const MAX_GROUP: usize;
    /// Whether the hidden layer runs on [`Pair`]s (which does not change any value).
    const PAIRED: bool;

    fn splat(value: f32) -> Self;
    /// The eight values at `values[start..start + 8]`.
    fn load(values: &[f32], start: usize) -> Self;
    /// Writes the lanes to `values[start..start + 8]`.
    fn store(self, values: &mut [f32], start: usize);
    fn add(self, other: Self) -> Self;
    fn sub(self, other: Self) -> Self;
    fn mul(self, other: Self) -> Self;
    fn div(self, other: Self) -> Self;
    fn min(self, other: Self) -> Self;
    fn max(self, other: Self) -> Self;
    fn neg(self) -> Self;
    /// `f32::from_bits((shifted.to_bits() + 127) << 23)` (wrapping), lane by lane: 2ⁿ
    /// for the integer `n` that adding [`ROUND`] left in the low bits of `shifted`.
    fn two_to_the_rounded(shifted: Self) -> Self;
    /// The first `count` lanes (0 to 7) kept, the others `+0`.
    fn keep_first(self, count: usize) -> Self;

    /// [`super::activation::exp`] of each lane, with its bits.
    #[inline(always)]
    fn exp(self) -> Self {
        exp_lanes(self)
    }
}

/// Eight lanes in an array: the reference, and the code every target without AVX2 or
/// WebAssembly's SIMD runs. (In a WebAssembly build with SIMD only the tests use it.)
#[derive(Clone, Copy)]
#[cfg_attr(
    all(target_arch = "wasm32", target_feature = "simd128"),
    allow(dead_code)
)]
pub(crate) struct Portable([f32; 8]);

#[cfg_attr(
    all(target_arch = "wasm32", target_feature = "simd128"),
    allow(dead_code)
)]
impl Portable {
    #[inline(always)]
    fn map(self, f: impl Fn(f32) -> f32) -> Self {
        Portable(self.0.map(f))
    }

    #[inline(always)]
    fn map2(self, other: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        let (a, b) = (self.0, other.0);
        Portable(std::array::from_fn(|lane| f(a[lane], b[lane])))
    }
}

impl Lanes for Portable {
    const WIDTH: usize = LANES;
    // Without SIMD registers (wasm), a lane is a scalar register: eight lanes of six
    // accumulators would not fit.
    const MAX_GROUP: usize = 1;
    const PAIRED: bool = false;

    /// One lane after the other: the lanes' temporaries would not fit in scalar
    /// registers at once.
    #[inline(always)]
    fn exp(self) -> Self {
        self.map(super::activation::exp)
    }

    #[inline(always)]
    fn splat(value: f32) -> Self {
        Portable([value; 8])
    }

    #[inline(always)]
    fn load(values: &[f32], start: usize) -> Self {
        let mut lanes = [0.0; 8];
        lanes.copy_from_slice(&values[start..start + 8]);
        Portable(lanes)
    }

    #[inline(always)]
    fn store(self, values: &mut [f32], start: usize) {
        values[start..start + 8].copy_from_slice(&self.0);
    }

    #[inline(always)]
    fn add(self, other: Self) -> Self {
        self.map2(other, |a, b| a + b)
    }

    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        self.map2(other, |a, b| a - b)
    }

    #[inline(always)]
    fn mul(self, other: Self) -> Self {
        self.map2(other, |a, b| a * b)
    }

    #[inline(always)]
    fn div(self, other: Self) -> Self {
        self.map2(other, |a, b| a / b)
    }

    #[inline(always)]
    fn min(self, other: Self) -> Self {
        self.map2(other, |a, b| if a < b { a } else { b })
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        self.map2(other, |a, b| if a > b { a } else { b })
    }

    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|a| -a)
    }

    #[inline(always)]
    fn two_to_the_rounded(shifted: Self) -> Self {
        shifted.map(|x| f32::from_bits(x.to_bits().wrapping_add(127) << 23))
    }

    #[inline(always)]
    fn keep_first(self, count: usize) -> Self {
        let mut kept = self.0;
        for lane in kept.iter_mut().skip(count) {
            *lane = 0.0;
        }
        Portable(kept)
    }
}

/// Two vectors side by side (sixteen samples): the forward pass runs on pairs so that
/// two independent chains of the long `exp` computation overlap. Each half does exactly
/// what it would do alone.
#[derive(Clone, Copy)]
struct Pair<V>(V, V);

impl<V: Lanes> Lanes for Pair<V> {
    const WIDTH: usize = 2 * V::WIDTH;
    const MAX_GROUP: usize = V::MAX_GROUP;
    const PAIRED: bool = true;

    #[inline(always)]
    fn splat(value: f32) -> Self {
        Pair(V::splat(value), V::splat(value))
    }

    #[inline(always)]
    fn load(values: &[f32], start: usize) -> Self {
        Pair(V::load(values, start), V::load(values, start + LANES))
    }

    #[inline(always)]
    fn store(self, values: &mut [f32], start: usize) {
        self.0.store(values, start);
        self.1.store(values, start + LANES);
    }

    #[inline(always)]
    fn add(self, other: Self) -> Self {
        Pair(self.0.add(other.0), self.1.add(other.1))
    }

    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        Pair(self.0.sub(other.0), self.1.sub(other.1))
    }

    #[inline(always)]
    fn mul(self, other: Self) -> Self {
        Pair(self.0.mul(other.0), self.1.mul(other.1))
    }

    #[inline(always)]
    fn div(self, other: Self) -> Self {
        Pair(self.0.div(other.0), self.1.div(other.1))
    }

    #[inline(always)]
    fn min(self, other: Self) -> Self {
        Pair(self.0.min(other.0), self.1.min(other.1))
    }

    #[inline(always)]
    fn max(self, other: Self) -> Self {
        Pair(self.0.max(other.0), self.1.max(other.1))
    }

    #[inline(always)]
    fn neg(self) -> Self {
        Pair(self.0.neg(), self.1.neg())
    }

    #[inline(always)]
    fn two_to_the_rounded(shifted: Self) -> Self {
        Pair(
            V::two_to_the_rounded(shifted.0),
            V::two_to_the_rounded(shifted.1),
        )
    }

    /// Here `count` is 0 to 15.
    #[inline(always)]
    fn keep_first(self, count: usize) -> Self {
        if count >= LANES {
            Pair(self.0, self.1.keep_first(count - LANES))
        } else {
            Pair(self.0.keep_first(count), self.1.keep_first(0))
        }
    }
}

/// `activation::exp`, operation for operation, on eight lanes.
#[inline(always)]
fn exp_lanes<V: Lanes>(x: V) -> V {
    let x = x.min(V::splat(EXP_LIMIT)).max(V::splat(-EXP_LIMIT));
    let shifted = x
        .mul(V::splat(std::f32::consts::LOG2_E))
        .add(V::splat(ROUND));
    let n = shifted.sub(V::splat(ROUND));
    let r = x.sub(n.mul(V::splat(LN2_HI))).sub(n.mul(V::splat(LN2_LO)));
    let c = |k: usize| V::splat(EXP_COEFFICIENTS[k]);
    let mut p = c(0);
    for k in 1..EXP_COEFFICIENTS.len() {
        p = p.mul(r).add(c(k));
    }
    let e = p.mul(r.mul(r)).add(r).add(V::splat(1.0));
    e.mul(V::two_to_the_rounded(shifted))
}

/// [`Activation::of`] on eight lanes, with its bits.
#[inline(always)]
fn activate<V: Lanes>(activation: Activation, z: V) -> V {
    let one = V::splat(1.0);
    match activation {
        Activation::Logistic => one.div(one.add(z.neg().exp())),
        Activation::Tanh => {
            let two = V::splat(2.0);
            one.sub(two.div(two.mul(z).exp().add(one)))
        }
    }
}

/// [`Activation::derivative`] on eight lanes, with its bits.
#[inline(always)]
fn derivative<V: Lanes>(activation: Activation, h: V) -> V {
    let one = V::splat(1.0);
    match activation {
        Activation::Logistic => h.mul(one.sub(h)),
        Activation::Tanh => one.sub(h.mul(h)),
    }
}

/// The network and the samples one part is evaluated on.
pub(crate) struct PartInput<'a> {
    pub shape: Shape,
    pub activation: Activation,
    /// `[W₁ | b₁ | W₂ | b₂]` as in [`Shape::split`], rounded to `f32`.
    pub params: &'a [f32],
    /// `inputs[i·stride + s]`: input `i` of sample `s`; readable up to the end of the
    /// range rounded up to a whole [`PAIR`].
    pub inputs: &'a [f32],
    /// `targets[k·stride + s]`, likewise.
    pub targets: &'a [f32],
    pub stride: usize,
}

/// One part's scratch space, allocated once per batch (and thread).
pub(crate) struct Scratch {
    /// Activations of one chunk, `hidden[j·CHUNK + s]`; then their deltas.
    hidden: Vec<f32>,
    /// Residuals of one chunk, `residuals[k·CHUNK + s]`.
    residuals: Vec<f32>,
    /// Eight lane sums per quantity of [`evaluate_part`]'s `sums`, over one chunk.
    lanes: Vec<f32>,
}

impl Scratch {
    pub fn new(shape: Shape) -> Self {
        Scratch {
            hidden: vec![0.0; shape.n_hidden * CHUNK],
            residuals: vec![0.0; shape.n_outputs * CHUNK],
            lanes: vec![0.0; LANES * (shape.n_outputs + shape.n_params())],
        }
    }
}

/// Evaluates the samples `range` (a part): writes to `sums[k]` the sum of squared
/// residuals of output `k` and, when `sums` is longer, to `sums[n_outputs + p]` the sum
/// over the samples of the derivative of `|r|²/2` by parameter `p` (no penalty, not
/// divided by the number of samples).
pub(crate) fn evaluate_part(
    input: &PartInput,
    range: std::ops::Range<usize>,
    scratch: &mut Scratch,
    sums: &mut [f64],
) {
    #[cfg(target_arch = "x86_64")]
    if avx2::is_available() {
        // SAFETY: the processor has AVX2 (checked just above).
        unsafe { avx2::evaluate_part(input, range, scratch, sums) };
        return;
    }
    #[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
    {
        part::<simd128::Simd128>(input, range, scratch, sums);
    }
    #[cfg(not(all(target_arch = "wasm32", target_feature = "simd128")))]
    part::<Portable>(input, range, scratch, sums);
}

/// [`evaluate_part`] in the portable lanes, whatever the processor (for tests).
#[cfg(test)]
pub(crate) fn evaluate_part_portable(
    input: &PartInput,
    range: std::ops::Range<usize>,
    scratch: &mut Scratch,
    sums: &mut [f64],
) {
    part::<Portable>(input, range, scratch, sums);
}

/// Adds each quantity's eight lane sums, reduced in `f64` in the order of the module
/// documentation, to its sum.
fn add_lane_sums(lanes: &[f32], sums: &mut [f64]) {
    for (sum, lane) in sums.iter_mut().zip(lanes.chunks_exact(LANES)) {
        let l = |k: usize| f64::from(lane[k]);
        *sum += ((l(0) + l(1)) + (l(2) + l(3))) + ((l(4) + l(5)) + (l(6) + l(7)));
    }
}

/// Runs `$body` with `$i` bound to each constant `0..$n` (`$n` ≤ 8, a constant), so that
/// arrays indexed by `$i` live in registers even where the compiler does not unroll.
macro_rules! unrolled {
    ($n:expr, |$i:ident| $body:block) => {{
        unrolled!(@one $n, 0, $i, $body);
        unrolled!(@one $n, 1, $i, $body);
        unrolled!(@one $n, 2, $i, $body);
        unrolled!(@one $n, 3, $i, $body);
        unrolled!(@one $n, 4, $i, $body);
        unrolled!(@one $n, 5, $i, $body);
        unrolled!(@one $n, 6, $i, $body);
        unrolled!(@one $n, 7, $i, $body);
    }};
    (@one $n:expr, $k:expr, $i:ident, $body:block) => {
        if $k < $n {
            let $i: usize = $k;
            $body
        }
    };
}

/// Where a neuron's quantities lie in the flat parameter vector (offset by the outputs'
/// sums of squares in `sums` and in the lanes).
struct Offsets {
    hidden_weights: usize,
    hidden_biases: usize,
    output_weights: usize,
    output_biases: usize,
}

impl Offsets {
    fn of(shape: Shape) -> Self {
        let hidden_weights = shape.n_outputs;
        let hidden_biases = hidden_weights + shape.n_inputs * shape.n_hidden;
        let output_weights = hidden_biases + shape.n_hidden;
        let output_biases = output_weights + shape.n_hidden * shape.n_outputs;
        Offsets {
            hidden_weights,
            hidden_biases,
            output_weights,
            output_biases,
        }
    }
}

/// The kernel; see the module documentation.
#[inline(always)]
fn part<V: Lanes>(
    input: &PartInput,
    range: std::ops::Range<usize>,
    scratch: &mut Scratch,
    sums: &mut [f64],
) {
    let shape = input.shape;
    let (n_inputs, n_hidden, n_outputs) = (shape.n_inputs, shape.n_hidden, shape.n_outputs);
    let params = shape.split(input.params);
    let with_gradient = sums.len() > n_outputs;
    let n_quantities = if with_gradient {
        n_outputs + shape.n_params()
    } else {
        n_outputs
    };
    let offsets = Offsets::of(shape);
    let stride = input.stride;
    let Scratch {
        hidden,
        residuals,
        lanes,
    } = scratch;
    let lanes = &mut lanes[..LANES * n_quantities];
    let sums = &mut sums[..n_quantities];
    sums.fill(0.0);

    let mut chunk_start = range.start;
    while chunk_start < range.end {
        lanes.fill(0.0);
        let chunk_len = CHUNK.min(range.end - chunk_start);
        let n_vectors = chunk_len.div_ceil(LANES);

        // Hidden layer: h = f(b₁ + W₁·x), one neuron (a row of the chunk) at a time.
        if V::PAIRED {
            hidden_layer::<Pair<V>>(input, &params, chunk_start, chunk_len, hidden);
        } else {
            hidden_layer::<V>(input, &params, chunk_start, chunk_len, hidden);
        }

        // Output layer and residuals: r = b₂ + W₂·h − t, and Σ r².
        for (output_idx, (weights, bias)) in params
            .output_weights
            .chunks_exact(n_hidden)
            .zip(params.output_biases)
            .enumerate()
        {
            let mut sum_squares = V::load(lanes, LANES * output_idx);
            let residual_row = &mut residuals[output_idx * CHUNK..][..CHUNK];
            for vector_idx in 0..n_vectors {
                let sample = chunk_start + LANES * vector_idx;
                let mut r = V::splat(*bias);
                for (neuron_idx, weight) in weights.iter().enumerate() {
                    let h = V::load(hidden, neuron_idx * CHUNK + LANES * vector_idx);
                    r = r.add(V::splat(*weight).mul(h));
                }
                r = r.sub(V::load(input.targets, output_idx * stride + sample));
                if sample + LANES > range.end {
                    r = r.keep_first(range.end - sample);
                }
                r.store(residual_row, LANES * vector_idx);
                sum_squares = sum_squares.add(r.mul(r));
            }
            sum_squares.store(lanes, LANES * output_idx);
        }
        if !with_gradient {
            add_lane_sums(lanes, sums);
            chunk_start += CHUNK;
            continue;
        }

        // Output biases: Σ r.
        for output_idx in 0..n_outputs {
            let at = LANES * (offsets.output_biases + output_idx);
            let mut sum = V::load(lanes, at);
            for vector_idx in 0..n_vectors {
                sum = sum.add(V::load(residuals, output_idx * CHUNK + LANES * vector_idx));
            }
            sum.store(lanes, at);
        }

        for neuron_idx in 0..n_hidden {
            let row = &mut hidden[neuron_idx * CHUNK..][..CHUNK];
            // Output weights of the second and later outputs: Σ rₖ·hⱼ (the first
            // output's is taken in the pass below, before hⱼ becomes δⱼ).
            for output_idx in 1..n_outputs {
                let at = LANES * (offsets.output_weights + output_idx * n_hidden + neuron_idx);
                let mut sum = V::load(lanes, at);
                for vector_idx in 0..n_vectors {
                    let r = V::load(residuals, output_idx * CHUNK + LANES * vector_idx);
                    sum = sum.add(r.mul(V::load(row, LANES * vector_idx)));
                }
                sum.store(lanes, at);
            }
            // δⱼ = (Σₖ W₂ₖⱼ·rₖ)·f'(hⱼ) written over hⱼ, with Σ r₀·hⱼ, Σ δⱼ and Σ δⱼ·xᵢ
            // for the first group of inputs; then the other groups from the stored δⱼ.
            let neuron = Neuron {
                activation: input.activation,
                idx: neuron_idx,
                n_hidden,
                output_weights: params.output_weights,
                n_outputs,
            };
            let first = n_inputs.min(V::MAX_GROUP);
            let pass = Pass {
                inputs: input.inputs,
                stride,
                chunk_start,
                n_vectors,
                first_input: 0,
                weight_lanes: LANES * (offsets.hidden_weights + neuron_idx * n_inputs),
            };
            let bias_lanes = LANES * (offsets.hidden_biases + neuron_idx);
            let output_weight_lanes = LANES * (offsets.output_weights + neuron_idx);
            let deltas = Deltas {
                neuron: &neuron,
                residuals,
                bias_lanes,
                output_weight_lanes,
            };
            match first {
                1 => delta_pass::<V, 1>(&pass, &deltas, row, lanes),
                2 => delta_pass::<V, 2>(&pass, &deltas, row, lanes),
                3 => delta_pass::<V, 3>(&pass, &deltas, row, lanes),
                4 => delta_pass::<V, 4>(&pass, &deltas, row, lanes),
                5 => delta_pass::<V, 5>(&pass, &deltas, row, lanes),
                _ => delta_pass::<V, MAX_GROUP>(&pass, &deltas, row, lanes),
            }
            let mut group_start = first;
            while group_start < n_inputs {
                let group = (n_inputs - group_start).min(V::MAX_GROUP);
                let pass = Pass {
                    first_input: group_start,
                    ..pass
                };
                match group {
                    1 => input_pass::<V, 1>(&pass, row, lanes),
                    2 => input_pass::<V, 2>(&pass, row, lanes),
                    3 => input_pass::<V, 3>(&pass, row, lanes),
                    4 => input_pass::<V, 4>(&pass, row, lanes),
                    5 => input_pass::<V, 5>(&pass, row, lanes),
                    _ => input_pass::<V, MAX_GROUP>(&pass, row, lanes),
                }
                group_start += group;
            }
        }
        add_lane_sums(lanes, sums);
        chunk_start += CHUNK;
    }
}

/// `h = f(b₁ + W₁·x)` of every neuron for the chunk's samples, `W::WIDTH` at a time,
/// into `hidden[j·CHUNK + s]`.
#[inline(always)]
fn hidden_layer<W: Lanes>(
    input: &PartInput,
    params: &super::loss::Blocks<&[f32]>,
    chunk_start: usize,
    chunk_len: usize,
    hidden: &mut [f32],
) {
    let n_values = chunk_len.div_ceil(W::WIDTH);
    for ((row, weights), bias) in hidden
        .chunks_exact_mut(CHUNK)
        .zip(params.hidden_weights.chunks_exact(input.shape.n_inputs))
        .zip(params.hidden_biases)
    {
        for value_idx in 0..n_values {
            let at = W::WIDTH * value_idx;
            let mut z = W::splat(*bias);
            for (input_idx, weight) in weights.iter().enumerate() {
                let x = W::load(input.inputs, input_idx * input.stride + chunk_start + at);
                z = z.add(W::splat(*weight).mul(x));
            }
            activate(input.activation, z).store(row, at);
        }
    }
}

/// One hidden neuron's view of the output layer.
struct Neuron<'a> {
    activation: Activation,
    idx: usize,
    n_hidden: usize,
    /// `W₂` (outputs × hidden, row-major).
    output_weights: &'a [f32],
    n_outputs: usize,
}

/// A pass over one chunk for one neuron and a group of inputs.
#[derive(Clone, Copy)]
struct Pass<'a> {
    inputs: &'a [f32],
    stride: usize,
    chunk_start: usize,
    n_vectors: usize,
    first_input: usize,
    /// Where the lanes of the neuron's first input weight lie.
    weight_lanes: usize,
}

/// What the delta pass needs beyond [`Pass`].
struct Deltas<'a> {
    neuron: &'a Neuron<'a>,
    residuals: &'a [f32],
    bias_lanes: usize,
    output_weight_lanes: usize,
}

/// `δ = (Σₖ W₂ₖⱼ·rₖ)·f'(h)` over `row` (which holds `h`), accumulating `Σ r₀·h`, `Σ δ`
/// and `Σ δ·xᵢ` for the `G` inputs from `pass.first_input`.
#[inline(always)]
fn delta_pass<V: Lanes, const G: usize>(
    pass: &Pass,
    deltas: &Deltas,
    row: &mut [f32],
    lanes: &mut [f32],
) {
    let neuron = deltas.neuron;
    let first_weight = V::splat(neuron.output_weights[neuron.idx]);
    let mut output_weight_sum = V::load(lanes, deltas.output_weight_lanes);
    let mut bias_sum = V::load(lanes, deltas.bias_lanes);
    let mut weight_sums = [V::splat(0.0); G];
    unrolled!(G, |i| {
        weight_sums[i] = V::load(lanes, pass.weight_lanes + LANES * (pass.first_input + i));
    });
    let input_rows = pass.first_input * pass.stride + pass.chunk_start;
    for vector_idx in 0..pass.n_vectors {
        let at = LANES * vector_idx;
        let h = V::load(row, at);
        let r = V::load(deltas.residuals, at);
        output_weight_sum = output_weight_sum.add(r.mul(h));
        let mut back = first_weight.mul(r);
        for output_idx in 1..neuron.n_outputs {
            let weight = neuron.output_weights[output_idx * neuron.n_hidden + neuron.idx];
            let r = V::load(deltas.residuals, output_idx * CHUNK + at);
            back = back.add(V::splat(weight).mul(r));
        }
        let delta = back.mul(derivative(neuron.activation, h));
        delta.store(row, at);
        bias_sum = bias_sum.add(delta);
        unrolled!(G, |i| {
            let x = V::load(pass.inputs, input_rows + i * pass.stride + at);
            weight_sums[i] = weight_sums[i].add(delta.mul(x));
        });
    }
    output_weight_sum.store(lanes, deltas.output_weight_lanes);
    bias_sum.store(lanes, deltas.bias_lanes);
    unrolled!(G, |i| {
        weight_sums[i].store(lanes, pass.weight_lanes + LANES * (pass.first_input + i));
    });
}

/// `Σ δ·xᵢ` for the `G` inputs from `pass.first_input`, `row` holding `δ`.
#[inline(always)]
fn input_pass<V: Lanes, const G: usize>(pass: &Pass, row: &[f32], lanes: &mut [f32]) {
    let mut weight_sums = [V::splat(0.0); G];
    unrolled!(G, |i| {
        weight_sums[i] = V::load(lanes, pass.weight_lanes + LANES * (pass.first_input + i));
    });
    let input_rows = pass.first_input * pass.stride + pass.chunk_start;
    for vector_idx in 0..pass.n_vectors {
        let at = LANES * vector_idx;
        let delta = V::load(row, at);
        unrolled!(G, |i| {
            let x = V::load(pass.inputs, input_rows + i * pass.stride + at);
            weight_sums[i] = weight_sums[i].add(delta.mul(x));
        });
    }
    unrolled!(G, |i| {
        weight_sums[i].store(lanes, pass.weight_lanes + LANES * (pass.first_input + i));
    });
}

#[cfg(target_arch = "x86_64")]
mod avx2;

#[cfg(all(target_arch = "wasm32", target_feature = "simd128"))]
mod simd128;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::base::rng::SplitMix64;

    // Also in the browser (`cargo test --target wasm32-unknown-unknown`), where the fast
    // kernel is the SIMD one.
    #[cfg_attr(not(target_arch = "wasm32"), test)]
    #[cfg_attr(target_arch = "wasm32", wasm_bindgen_test::wasm_bindgen_test)]
    fn exp_on_lanes_gives_the_scalar_bits() {
        let mut rng = SplitMix64::new(1);
        for _ in 0..2000 {
            let values: [f32; 8] = std::array::from_fn(|_| (30.0 * rng.gaussian()) as f32);
            let lanes = exp_lanes(Portable(values));
            for (lane, value) in lanes.0.iter().zip(values) {
                assert_eq!(
                    lane.to_bits(),
                    super::super::activation::exp(value).to_bits()
                );
            }
        }
    }

    /// Random normalised data, `stride` long columns padded with zeros.
    fn case(shape: Shape, n: usize, seed: u64) -> (Vec<f32>, Vec<f32>, Vec<f32>, usize) {
        let mut rng = SplitMix64::new(seed);
        let stride = n + PAIR;
        let mut inputs = vec![0.0; shape.n_inputs * stride];
        let mut targets = vec![0.0; shape.n_outputs * stride];
        for column in inputs.chunks_exact_mut(stride) {
            for value in &mut column[..n] {
                *value = (2.0 * rng.gaussian()) as f32;
            }
        }
        for column in targets.chunks_exact_mut(stride) {
            for value in &mut column[..n] {
                *value = rng.gaussian() as f32;
            }
        }
        let params = (0..shape.n_params())
            .map(|_| rng.uniform_in(-1.5, 1.5) as f32)
            .collect();
        (inputs, targets, params, stride)
    }

    // Also in the browser (`cargo test --target wasm32-unknown-unknown`), where the fast
    // kernel is the SIMD one.
    #[cfg_attr(not(target_arch = "wasm32"), test)]
    #[cfg_attr(target_arch = "wasm32", wasm_bindgen_test::wasm_bindgen_test)]
    fn the_fast_kernel_gives_the_portable_bits() {
        for (n_inputs, n_hidden, n_outputs) in [(5, 15, 1), (1, 3, 1), (9, 4, 2), (13, 2, 3)] {
            let shape = Shape {
                n_inputs,
                n_hidden,
                n_outputs,
            };
            let (inputs, targets, params, stride) = case(shape, 300, 2);
            for activation in [Activation::Logistic, Activation::Tanh] {
                let input = PartInput {
                    shape,
                    activation,
                    params: &params,
                    inputs: &inputs,
                    targets: &targets,
                    stride,
                };
                for range in [0..300, 3..4, 17..290, 0..128, 1..130] {
                    for with_gradient in [false, true] {
                        let len = n_outputs + if with_gradient { shape.n_params() } else { 0 };
                        let mut fast = vec![f64::NAN; len];
                        let mut portable = vec![f64::NAN; len];
                        evaluate_part(&input, range.clone(), &mut Scratch::new(shape), &mut fast);
                        evaluate_part_portable(
                            &input,
                            range.clone(),
                            &mut Scratch::new(shape),
                            &mut portable,
                        );
                        let bits = |values: &[f64]| -> Vec<u64> {
                            values.iter().map(|value| value.to_bits()).collect()
                        };
                        assert_eq!(bits(&fast), bits(&portable), "{shape:?} {range:?}");
                        assert!(portable.iter().all(|value| value.is_finite()));
                    }
                }
            }
        }
    }
}
