// Leaves a benchmark page's results where bench/wasm-bench.mjs reads them
// (`window.benchResults`, or `window.benchError`), shows them, and marks the page done.
export function report(results) {
  results.then(
    (value) => {
      window.benchResults = value;
      document.body.dataset.state = 'done';
    },
    (error) => {
      window.benchError = String((error && error.stack) || error);
      document.getElementById('status').textContent = window.benchError;
      document.body.dataset.state = 'error';
    },
  );
}
