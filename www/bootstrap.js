// Loads the WebAssembly module and hands the page to it. Everything else is in Rust
// (src/web/), except the service worker (sw.js), which keeps the page for offline use.
import init, { run_page } from './pkg/compass_pdr.js';

const status = document.getElementById('status');
try {
  await init();
  run_page();
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
