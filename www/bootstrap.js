// Loads the WebAssembly module and hands the page to it. Everything else is in Rust
// (src/web/), except the service worker (sw.js), which keeps the page for offline use,
// the analysis worker (analysis-worker.js) and the import workers (threads.js,
// pool-worker.js).
//
// Two builds of one crate: pkg/ runs on one thread anywhere; pkg-threads/ shares its
// memory with Web Workers, so large files are read on every core (src/par.rs). The
// browser allows shared memory only on a cross-origin isolated page (served with
// COOP/COEP headers: ./run's server does, and sw.js adds them), and only then is
// pkg-threads used.

import { startAnalysisWorker, startWorkers, whenWorkersReady } from './threads.js';

const status = document.getElementById('status');
const engine = document.getElementById('engine');

/** The module's exports: the threaded build when it can run here, else the plain one. */
async function load() {
  if (self.crossOriginIsolated) {
    try {
      const threaded = await import('./pkg-threads/compass_pdr.js');
      await threaded.default();
      return { wasm: threaded, threaded: true };
    } catch (error) {
      console.warn(`compass-pdr: the threaded module did not load, using one thread: ${error}`);
    }
  }
  const plain = await import('./pkg/compass_pdr.js');
  await plain.default();
  return { wasm: plain, threaded: false };
}

/** A panic (a bug) ends in a trap, which reaches the page as a WebAssembly.RuntimeError
 * after the panic hook has put its message in the status line (src/web/mod.rs); a trap
 * without that message (one not from a panic) is reported here as the hook reports one. */
function showTrap(error) {
  if (!(error instanceof WebAssembly.RuntimeError)) return;
  if (document.body.dataset.state === 'error' && status.textContent.startsWith('Internal error')) return;
  document.body.dataset.state = 'error';
  status.textContent = `Internal error (a bug in compass-pdr): ${error.message}. Reload the page to continue, and please report it.`;
}
window.addEventListener('error', (event) => showTrap(event.error));
window.addEventListener('unhandledrejection', (event) => showTrap(event.reason));

/** Says in the footer how many threads imports use. */
function showEngine(threaded, nThreads, nCores) {
  document.body.dataset.threads = String(nThreads);
  engine.textContent = threaded
    ? `Large files are read on ${nThreads} of this computer's ${nCores} threads (WebAssembly threads).`
    : 'Files are read on one thread: this page is not cross-origin isolated, so WebAssembly threads are off.';
}

try {
  const { wasm, threaded } = await load();
  const nWorkers = threaded ? startWorkers(wasm) : 0;
  // The logs are read and analysed on a worker where the memory can be shared with it.
  wasm.run_page(threaded ? startAnalysisWorker(wasm) : undefined);
  showEngine(threaded, 1, nWorkers + 1);
  if (threaded) {
    whenWorkersReady(wasm, nWorkers, { onChange: (nThreads) => showEngine(true, nThreads, nWorkers + 1) });
  }
} catch (error) {
  document.body.dataset.state = 'error';
  status.textContent = `The page could not start: ${error}. Use a current Chromium, Firefox or Safari.`;
  console.error(error);
}

// Offline after the first visit. A browser without service workers (or a file:// page)
// simply needs the network each time.
if ('serviceWorker' in navigator && location.protocol !== 'file:') {
  navigator.serviceWorker.register('sw.js').catch((error) => console.warn(`compass-pdr: no offline copy: ${error}`));
}
