"""Serves a folder on 127.0.0.1 with the headers that make the page cross-origin
isolated (COOP: same-origin, COEP: require-corp), so that the browser allows
WebAssembly threads (www/bootstrap.js then loads pkg-threads/).

    python3 scripts/serve.py PORT FOLDER
"""

import functools
import http.server
import sys


class IsolatedHandler(http.server.SimpleHTTPRequestHandler):
    def end_headers(self):
        self.send_header("Cross-Origin-Opener-Policy", "same-origin")
        self.send_header("Cross-Origin-Embedder-Policy", "require-corp")
        super().end_headers()


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: serve.py PORT FOLDER")
    port, folder = int(sys.argv[1]), sys.argv[2]
    handler = functools.partial(IsolatedHandler, directory=folder)
    with http.server.ThreadingHTTPServer(("127.0.0.1", port), handler) as server:
        print(f"Serving {folder} on http://127.0.0.1:{port}/ (cross-origin isolated)", flush=True)
        server.serve_forever()


if __name__ == "__main__":
    main()
