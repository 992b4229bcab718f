// One worker of the threaded module's pool (src/par.rs). It instantiates the module the
// page compiled on the page's shared memory, then waits in Rust (`pool_worker`) for
// parts of a large import; that call never returns. If it traps (a panic), the part is
// reported lost, the page does the work again on one thread, and this worker stops.
import { initSync, pool_worker, pool_worker_failed } from './pkg-threads/compass_pdr.js';

self.onmessage = ({ data: { module, memory, workerIdx } }) => {
  initSync({ module, memory });
  try {
    pool_worker(workerIdx);
  } catch (error) {
    pool_worker_failed(workerIdx);
    console.error(`compass-pdr: worker ${workerIdx} stopped: ${error}`);
  }
};
