// Loads the WebAssembly module and hands the page to it. Everything else is in Rust
// (src/web/).
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
