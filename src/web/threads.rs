//! The threaded module's Web Workers ([`crate::base::par::pool`]): what `www/bootstrap.js`
//! and `www/pool-worker.js` call to start them. Only in the threaded build
//! (`target_feature = "atomics"`), which the page loads when it is cross-origin
//! isolated.

use wasm_bindgen::prelude::*;

use crate::base::par::pool;

/// This module, for a worker to instantiate on the same memory.
#[wasm_bindgen]
pub fn pool_module() -> JsValue {
    wasm_bindgen::module()
}

/// This module's (shared) memory.
#[wasm_bindgen]
pub fn pool_memory() -> JsValue {
    wasm_bindgen::memory()
}

/// How many workers the pool can hold.
#[wasm_bindgen]
pub fn pool_max_workers() -> usize {
    pool::MAX_WORKERS
}

/// Threads an import can use now: this one and the workers waiting for work.
#[wasm_bindgen]
pub fn pool_threads() -> usize {
    crate::base::par::n_threads()
}

/// A worker's life (never returns): waits for parts of the work and runs them.
#[wasm_bindgen]
pub fn pool_worker(worker_idx: usize) {
    pool::serve(worker_idx);
}

/// Called by a worker whose [`pool_worker`] trapped (a panic): its part is reported
/// lost, so the import is done again on one thread, and it gets no more work.
#[wasm_bindgen]
pub fn pool_worker_failed(worker_idx: usize) {
    pool::fail(worker_idx);
}
