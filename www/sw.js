// The service worker: the page works offline after the first visit.
//
// Every request of the page's own origin goes to the network first (so a new version
// is used as soon as it is served) and, when the network fails, to the copy kept from
// the last visit. The page asks for nothing else, and nothing after it has loaded:
// the logs it analyses are read from the user's disk and never sent anywhere.
//
// It also adds the two headers that make the page cross-origin isolated (COOP and COEP),
// so that from the second visit on the page can use WebAssembly threads
// (bootstrap.js, pkg-threads/) even where the host cannot send them. The page loads
// nothing from other origins, so requiring CORP of them costs nothing.
const CACHE = 'compass-pdr-v3';
// The threaded module is not listed: it is kept when first used, and the page falls
// back to pkg/ while it is missing (or when the build had no nightly Rust).
const SHELL = [
  './',
  'index.html',
  'style.css',
  'bootstrap.js',
  'threads.js',
  'pool-worker.js',
  'analysis-worker.js',
  'pkg/compass_pdr.js',
  'pkg/compass_pdr_bg.wasm',
  'pkg/demo-walk.csv',
];

self.addEventListener('install', (event) => {
  event.waitUntil(caches.open(CACHE).then((cache) => cache.addAll(SHELL)).then(() => self.skipWaiting()));
});

self.addEventListener('activate', (event) => {
  event.waitUntil(
    caches.keys()
      .then((keys) => Promise.all(keys.filter((key) => key !== CACHE).map((key) => caches.delete(key))))
      .then(() => self.clients.claim()),
  );
});

/** `response` with the cross-origin isolation headers (opaque responses as they are). */
function isolated(response) {
  if (response.type === 'opaque' || response.status === 0) return response;
  const headers = new Headers(response.headers);
  headers.set('Cross-Origin-Opener-Policy', 'same-origin');
  headers.set('Cross-Origin-Embedder-Policy', 'require-corp');
  return new Response(response.body, { status: response.status, statusText: response.statusText, headers });
}

self.addEventListener('fetch', (event) => {
  const request = event.request;
  if (request.method !== 'GET' || new URL(request.url).origin !== self.location.origin) return;
  event.respondWith(
    fetch(request)
      .then((response) => {
        if (response.ok) {
          const copy = response.clone();
          caches.open(CACHE).then((cache) => cache.put(request, copy));
        }
        return response;
      })
      .catch(() => caches.match(request, { ignoreSearch: true }).then((cached) => cached
        || new Response('compass-pdr is offline and this file was not kept from an earlier visit.', {
          status: 503, headers: { 'Content-Type': 'text/plain; charset=utf-8' },
        })))
      .then(isolated),
  );
});
