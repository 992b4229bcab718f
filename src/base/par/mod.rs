//! Work side by side on every core, the crate's one place for threads: [`on_each_part`]
//! runs one closure on each of a few parts and gives the results in order (the
//! importers' large-file paths, the 3D fit's starts), [`map`] maps a long slice in one
//! part per thread (the per-sample headings of an analysis), and [`Helpers`] keeps helper
//! threads for a run of many small jobs (the network's training batches; native only).
//!
//! Three builds, one contract (the results are in the parts' order, whichever thread
//! ran which part, so the callers' output does not depend on the number of threads):
//!
//! - **native**: the first part on this thread, each other on a scoped `std` thread.
//! - **WebAssembly without threads** (the page's default module): every part on this
//!   thread, one after the other.
//! - **WebAssembly with threads** (`target_feature = "atomics"`: the page's second module,
//!   loaded when the page is cross-origin isolated): the first part on this thread,
//!   the others on Web Workers that share the module's memory. The page starts the
//!   workers (`www/pool-worker.js`); each calls `pool::serve` (through
//!   `src/web/threads.rs`) and waits there for parts. The browser's main thread may
//!   not block, so it never waits on a lock or a futex for the workers: it spins on
//!   each part's state once its own part is done (the parts are cut to take about
//!   equal time). A worker that panics traps (the build aborts on panic); its page
//!   script reports it (`pool::fail`), the work is then done again on one thread,
//!   and the worker gets no more. (Were it to trap while holding the allocator's
//!   lock, the page would hang: the importers' tests, proptest included, find no
//!   panic to make that happen.) This pool is the crate's one piece of global state outside `web`:
//!   like the allocator, it is the runtime's, not the algorithms'. (`pool`: a slot per
//!   worker, the job handed over by its address, the workers waiting with
//!   `memory.atomic.wait32`; its code is not generic, so it is compiled once.) The small
//!   pieces ([`map`], a row's two statistics, the gravity filter's two passes) stay on
//!   one thread in this module ([`SMALL_WORK_IN_PARALLEL`]): a copy of the pool for each
//!   caller's types would cost more of the module's size budget than they save in time.

mod helpers;

pub use helpers::Helpers;

/// How many threads [`on_each_part`] can use now, this one included: the parts a
/// caller should cut its work into.
pub fn n_threads() -> usize {
    #[cfg(not(target_arch = "wasm32"))]
    {
        // Asked once: the answer reads the system's limits, and hot loops ask often.
        static THREADS: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
        *THREADS.get_or_init(|| std::thread::available_parallelism().map_or(1, usize::from))
    }
    #[cfg(all(target_arch = "wasm32", target_feature = "atomics"))]
    {
        1 + pool::n_ready()
    }
    #[cfg(all(target_arch = "wasm32", not(target_feature = "atomics")))]
    {
        1
    }
}

/// How many worker threads have failed (trapped) so far: always 0 natively, where a
/// panicking thread unwinds (its drop guards run) and [`on_each_part`] reports it. In the
/// threaded browser build a panic aborts its worker with no unwinding; code that waits
/// for a worker's part by other means than [`on_each_part`] (`io::nmea::parallel`)
/// compares this count to tell a lost part from a slow one.
pub fn n_failures() -> usize {
    #[cfg(all(target_arch = "wasm32", target_feature = "atomics"))]
    {
        pool::n_failures()
    }
    #[cfg(not(all(target_arch = "wasm32", target_feature = "atomics")))]
    {
        0
    }
}

/// `work` on each item, the results in the items' order; `None` if a thread failed
/// (it panicked), in which case the caller does the work on one thread.
pub fn on_each_part<I, R>(items: I, work: impl Fn(I::Item) -> R + Sync) -> Option<Vec<R>>
where
    I: Iterator,
    I::Item: Send,
    R: Send,
{
    #[cfg(not(target_arch = "wasm32"))]
    {
        let mut items = items;
        let first = items.next();
        let work = &work;
        std::thread::scope(|scope| {
            let handles: Vec<_> = items.map(|item| scope.spawn(move || work(item))).collect();
            let mut results: Vec<R> = first.map(work).into_iter().collect();
            for handle in handles {
                results.push(handle.join().ok()?);
            }
            Some(results)
        })
    }
    #[cfg(all(target_arch = "wasm32", target_feature = "atomics"))]
    {
        pool::on_each_part(items, work)
    }
    #[cfg(all(target_arch = "wasm32", not(target_feature = "atomics")))]
    {
        Some(items.map(work).collect())
    }
}

/// Whether the small pieces of parallel work ([`map`], a pair of statistics, the
/// gravity filter's two passes) use several threads: natively yes; in the threaded
/// browser module no, where the pool's code compiled for each caller's types would
/// outgrow the module's size budget for a few tens of milliseconds (the importers and
/// the 3D fit, the long pieces, use the pool there).
pub const SMALL_WORK_IN_PARALLEL: bool =
    !cfg!(all(target_arch = "wasm32", target_feature = "atomics"));

/// [`on_each_part`] for a small piece of work: `None`, so that the caller works on
/// one thread, where [`SMALL_WORK_IN_PARALLEL`] is false.
pub fn on_each_small_part<I, R>(items: I, work: impl Fn(I::Item) -> R + Sync) -> Option<Vec<R>>
where
    I: Iterator,
    I::Item: Send,
    R: Send,
{
    if SMALL_WORK_IN_PARALLEL {
        on_each_part(items, work)
    } else {
        None
    }
}

/// Below this many items a part is not worth a thread of its own (starting one costs
/// tens of microseconds; an item of the per-sample maps below, tens of nanoseconds).
const MIN_ITEMS_PER_PART: usize = 20_000;

/// `f(index, item)` of every item, in the items' order: the per-sample maps of a long
/// recording (each method's heading at every sample, each model's correction), cut into
/// one contiguous part per thread. The result does not depend on the number of threads.
pub fn map<T, R>(items: &[T], f: impl Fn(usize, &T) -> R + Sync) -> Vec<R>
where
    T: Sync,
    R: Send,
{
    let sequential = || {
        items
            .iter()
            .enumerate()
            .map(|(idx, item)| f(idx, item))
            .collect()
    };
    let n_parts = n_threads().min(items.len() / MIN_ITEMS_PER_PART);
    if !SMALL_WORK_IN_PARALLEL || n_parts < 2 {
        return sequential();
    }
    let part_len = items.len().div_ceil(n_parts);
    let starts = (0..items.len()).step_by(part_len);
    let parts = on_each_part(starts, |start| {
        let part = items
            .get(start..(start + part_len).min(items.len()))
            .unwrap_or(&[]);
        part.iter()
            .enumerate()
            .map(|(offset, item)| f(start + offset, item))
            .collect::<Vec<R>>()
    });
    match parts {
        Some(parts) => parts.into_iter().flatten().collect(),
        None => sequential(),
    }
}

/// The Web Worker pool of the threaded WebAssembly build.
#[cfg(all(target_arch = "wasm32", target_feature = "atomics"))]
pub mod pool {
    use std::cell::Cell;
    use std::sync::atomic::{AtomicBool, AtomicI32, AtomicU32, AtomicUsize, Ordering};
    use std::sync::Mutex;

    /// At most this many workers (a bit each in [`READY`]).
    pub const MAX_WORKERS: usize = 31;

    /// A slot's states: no work, work handed over, work done, the worker failed.
    const IDLE: i32 = 0;
    const GIVEN: i32 = 1;
    const DONE: i32 = 2;
    const FAILED: i32 = 3;

    /// Where this thread's part of the work is handed to a worker.
    struct Slot {
        state: AtomicI32,
        /// The address of a `&(dyn Fn() + Sync)` on the handing thread's stack, valid
        /// until the state leaves `GIVEN` (the handing thread waits for that).
        job: AtomicUsize,
    }

    static SLOTS: [Slot; MAX_WORKERS] = [const {
        Slot {
            state: AtomicI32::new(IDLE),
            job: AtomicUsize::new(0),
        }
    }; MAX_WORKERS];

    /// Bit `i` set: worker `i` waits in [`serve`] for work.
    static READY: AtomicU32 = AtomicU32::new(0);

    /// Workers that trapped so far.
    static FAILURES: AtomicUsize = AtomicUsize::new(0);

    /// Set while a thread hands out parts; a second caller (or a worker) works alone.
    static IN_USE: AtomicBool = AtomicBool::new(false);

    thread_local! {
        static IS_WORKER: Cell<bool> = const { Cell::new(false) };
    }

    /// Workers that trapped so far.
    pub fn n_failures() -> usize {
        FAILURES.load(Ordering::Acquire)
    }

    /// Workers waiting for work now.
    pub fn n_ready() -> usize {
        READY.load(Ordering::Acquire).count_ones() as usize
    }

    /// A worker's life: waits for work in its slot, runs it, says it is done; never
    /// returns. `worker_idx` below [`MAX_WORKERS`]; a worker given a taken or out-of-range
    /// index returns at once and does nothing.
    pub fn serve(worker_idx: usize) {
        let Some(slot) = SLOTS.get(worker_idx) else {
            return;
        };
        let bit = 1u32 << worker_idx;
        if READY.fetch_or(bit, Ordering::AcqRel) & bit != 0 {
            return;
        }
        IS_WORKER.with(|is_worker| is_worker.set(true));
        loop {
            let state = slot.state.load(Ordering::Acquire);
            if state != GIVEN {
                // SAFETY: the pointer is to a live atomic; waiting is allowed on a
                // worker (only the browser's main thread may not block).
                unsafe {
                    core::arch::wasm32::memory_atomic_wait32(slot.state.as_ptr(), state, -1);
                }
                continue;
            }
            let job = slot.job.load(Ordering::Acquire) as *const &(dyn Fn() + Sync);
            // SAFETY: the handing thread keeps the closure alive until the state leaves
            // GIVEN, which only this worker does, after the call.
            unsafe { (*job)() };
            slot.state.store(DONE, Ordering::Release);
        }
    }

    /// Marks worker `worker_idx` failed (it trapped: a panic): its part is reported
    /// lost and it is given no more work.
    pub fn fail(worker_idx: usize) {
        let Some(slot) = SLOTS.get(worker_idx) else {
            return;
        };
        READY.fetch_and(!(1u32 << worker_idx), Ordering::AcqRel);
        slot.state.store(FAILED, Ordering::Release);
        FAILURES.fetch_add(1, Ordering::AcqRel);
    }

    /// Gives up [`IN_USE`] when dropped.
    struct InUse;
    impl Drop for InUse {
        fn drop(&mut self) {
            IN_USE.store(false, Ordering::Release);
        }
    }

    pub(super) fn on_each_part<I, R>(items: I, work: impl Fn(I::Item) -> R + Sync) -> Option<Vec<R>>
    where
        I: Iterator,
        I::Item: Send,
        R: Send,
    {
        let alone = IS_WORKER.with(Cell::get)
            || IN_USE
                .compare_exchange(false, true, Ordering::AcqRel, Ordering::Acquire)
                .is_err();
        if alone {
            return Some(items.map(work).collect());
        }
        let _in_use = InUse;
        // Each part: its input, taken once by whoever runs it, and its result.
        let inputs: Vec<Mutex<Option<I::Item>>> =
            items.map(|item| Mutex::new(Some(item))).collect();
        let outputs: Vec<Mutex<Option<R>>> = inputs.iter().map(|_| Mutex::new(None)).collect();
        let run = |part_idx: usize| {
            let input = inputs
                .get(part_idx)
                .and_then(|input| input.lock().ok()?.take());
            if let (Some(input), Some(output)) = (input, outputs.get(part_idx)) {
                let result = work(input);
                if let Ok(mut output) = output.lock() {
                    *output = Some(result);
                }
            }
        };
        if !run_parts(inputs.len(), &run) {
            return None;
        }
        outputs
            .into_iter()
            .map(|output| output.into_inner().ok().flatten())
            .collect()
    }

    /// Runs `run(part_idx)` for every part, part 0 and any beyond the workers here, the
    /// others on the workers; `false` if a worker failed. Not generic, so the pool's
    /// code is compiled once rather than for every caller's types.
    fn run_parts(n_parts: usize, run: &(dyn Fn(usize) + Sync)) -> bool {
        let ready = READY.load(Ordering::Acquire);
        let workers: Vec<usize> = (0..MAX_WORKERS)
            .filter(|&worker_idx| ready & (1 << worker_idx) != 0)
            .collect();
        // Parts 1.. to the workers, one each; the first, and any beyond the workers,
        // here.
        let jobs: Vec<Box<dyn Fn() + Sync + '_>> = (1..n_parts)
            .map(|part_idx| Box::new(move || run(part_idx)) as Box<dyn Fn() + Sync + '_>)
            .collect();
        let job_refs: Vec<&(dyn Fn() + Sync)> = jobs.iter().map(|job| job.as_ref()).collect();
        let mut given: Vec<&Slot> = Vec::new();
        let mut here: Vec<usize> = vec![0];
        for (job_idx, job_ref) in job_refs.iter().enumerate() {
            match workers
                .get(job_idx)
                .and_then(|&worker_idx| SLOTS.get(worker_idx))
            {
                Some(slot) => {
                    slot.job.store(
                        job_ref as *const &(dyn Fn() + Sync) as usize,
                        Ordering::Release,
                    );
                    slot.state.store(GIVEN, Ordering::Release);
                    // SAFETY: the pointer is to a live atomic.
                    unsafe { core::arch::wasm32::memory_atomic_notify(slot.state.as_ptr(), 1) };
                    given.push(slot);
                }
                None => here.push(job_idx + 1),
            }
        }
        for part_idx in here {
            run(part_idx);
        }
        // Spin (this may be the browser's main thread) until every worker is done.
        let mut failed = false;
        for slot in given {
            loop {
                match slot.state.load(Ordering::Acquire) {
                    GIVEN => core::hint::spin_loop(),
                    DONE => {
                        slot.state.store(IDLE, Ordering::Release);
                        break;
                    }
                    _ => {
                        failed = true;
                        break;
                    }
                }
            }
        }
        // Every job has returned or its worker is gone: the closures may be dropped.
        drop(job_refs);
        drop(jobs);
        !failed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn results_come_in_the_parts_order() {
        let parts: Vec<u64> = (0..7).collect();
        let results = on_each_part(parts.iter(), |&part| {
            // Later parts finish first.
            std::thread::sleep(std::time::Duration::from_millis(10 * (7 - part)));
            part * part
        });
        assert_eq!(results, Some(vec![0, 1, 4, 9, 16, 25, 36]));
    }

    #[test]
    fn no_parts_give_no_results() {
        assert_eq!(
            on_each_part(std::iter::empty::<u8>(), |byte| byte),
            Some(vec![])
        );
    }

    #[test]
    fn a_map_keeps_the_items_order_and_indices() {
        for n in [0, 1, 19_999, 20_000, 40_001, 100_003] {
            let items: Vec<u64> = (0..n as u64).map(|value| value * 3).collect();
            let mapped = map(&items, |idx, &item| (idx as u64, item + 1));
            let expected: Vec<(u64, u64)> = (0..n as u64).map(|idx| (idx, idx * 3 + 1)).collect();
            assert_eq!(mapped, expected, "{n} items");
        }
    }

    #[test]
    fn there_is_at_least_this_thread() {
        assert!(n_threads() >= 1);
    }
}
