// The threaded module's workers (src/par.rs), for the page (bootstrap.js) and the
// import benchmark (bench/wasm/bench.js). Each worker (pool-worker.js) instantiates the
// module on the page's shared memory and waits in Rust for parts of a large import.

/** Starts one worker per further core (at most the pool's size, and at most
 * `maxWorkers`); returns how many. */
export function startWorkers(wasm, maxWorkers = Infinity) {
  const cores = Math.max(1, navigator.hardwareConcurrency || 1);
  const nWorkers = Math.min(cores - 1, wasm.pool_max_workers(), maxWorkers);
  const module = wasm.pool_module();
  const memory = wasm.pool_memory();
  for (let workerIdx = 0; workerIdx < nWorkers; workerIdx += 1) {
    const worker = new Worker(new URL('pool-worker.js', import.meta.url), {
      type: 'module',
      name: `compass-pdr import ${workerIdx}`,
    });
    worker.postMessage({ module, memory, workerIdx });
  }
  return nWorkers;
}

/** Resolves with the threads an import can use once `nWorkers` workers wait for work,
 * or with fewer after `timeoutMs`; `onChange(nThreads)` is told of each change. */
export function whenWorkersReady(wasm, nWorkers, { timeoutMs = 10_000, onChange = () => {} } = {}) {
  const started = performance.now();
  let last = 0;
  return new Promise((resolve) => {
    const poll = () => {
      const nThreads = wasm.pool_threads();
      if (nThreads !== last) onChange(nThreads);
      last = nThreads;
      if (nThreads >= nWorkers + 1 || performance.now() - started > timeoutMs) resolve(nThreads);
      else setTimeout(poll, 20);
    };
    poll();
  });
}

/** Starts the analysis worker (analysis-worker.js, src/web/worker.rs) on the module's
 * memory: the page hands it the logs to read and analyse, and stays free meanwhile. */
export function startAnalysisWorker(wasm) {
  const worker = new Worker(new URL('analysis-worker.js', import.meta.url), {
    type: 'module',
    name: 'compass-pdr analysis',
  });
  worker.postMessage({ module: wasm.pool_module(), memory: wasm.pool_memory() });
  // A job's timing, kept where a benchmark asked for it (bench/drop_costs.mjs sets
  // `window.__jobTimings` to an array), with when the page heard that the job was done.
  worker.addEventListener('message', ({ data }) => {
    // The warm-up's end (analysis-worker.js), on the page's body for its tests.
    if (data?.warmedUp !== undefined && self.document) {
      document.body.dataset.warmedUpMs = data.warmedUp.toFixed(0);
    }
    if (data?.done && data.timing && Array.isArray(self.__jobTimings)) {
      self.__jobTimings.push({ ...data.timing, receivedAt: performance.timeOrigin + performance.now() });
    }
  });
  return worker;
}
