"""The gallery's local HTTP server (``pact gallery OUT --serve``): OUT's files, and the
mask editor's endpoints under ``/api/editor`` (docs/gallery.md).

Static files: every file of OUT, as ``python -m http.server`` serves them, with the MIME
types the 3D view needs and ``Cache-Control: no-cache`` (a re-converted asset keeps its
file names, so the browser must ask again).

The editor (:class:`asset_pipeline.gallery.editor.MaskEditor`) is on only when the server
is bound to 127.0.0.1, and then:

- every ``/api/editor/*`` request must name this server in its ``Host`` header
  (``127.0.0.1:PORT``; a page of another site reached through a rebound DNS name
  cannot read the photos);
- a POST must come from the page's own origin (``Origin: http://127.0.0.1:PORT``, and
  ``Sec-Fetch-Site: same-origin`` when the browser sends it) with a JSON body
  (``Content-Type: application/json``, at most
  :data:`~asset_pipeline.gallery.editor.MAX_REQUEST_BYTES`); the server sends no CORS
  headers, so no other page may send one;
- an asset is named by its catalog id only; no path from a request is used as a path.

Endpoints (JSON unless said otherwise; errors are ``{"error": message}`` with a 4xx/5xx
status):

=========================================  ==================================================
``GET /api/editor``                        on or off (and why), motions and their words, categories
``GET /api/editor/asset?id=ID``            what the editor opens: photo size, mask ids, hints
``GET /api/editor/photo?id=ID``            the input photo as PNG (EXIF orientation applied)
``GET /api/editor/mask?id=ID``             the current part mask as an 8-bit grey PNG of ids
``POST /api/editor/save``                  check, write the two files, queue the re-conversion (202)
``GET /api/editor/status?job=N``           the re-conversion: queued, running (stage), done, failed
=========================================  ==================================================
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import logging
import sys
import threading
from collections.abc import Iterator, Mapping
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from asset_pipeline.catalog.registry import CatalogError
from asset_pipeline.gallery.editor import MAX_REQUEST_BYTES, EditRefused, MaskEditor
from asset_pipeline.gallery.page import write_gallery
from asset_pipeline.gallery.screenshots import ScreenshotError, screenshot

log = logging.getLogger(__name__)

API = "/api/editor"
#: The one interface the editor works on.
EDITOR_HOST = "127.0.0.1"


class GalleryHandler(SimpleHTTPRequestHandler):
    """Static files of OUT (quiet, no caching without asking) and the editor's API."""

    server: GalleryServer
    extensions_map = {
        **SimpleHTTPRequestHandler.extensions_map,
        ".js": "text/javascript",
        ".json": "application/json",
        ".glb": "model/gltf-binary",
    }

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - stdlib's name
        log.debug("%s " + format, self.address_string(), *args)

    def end_headers(self) -> None:
        self.send_header("Cache-Control", "no-cache")
        self.send_header("X-Content-Type-Options", "nosniff")
        super().end_headers()

    # ---- routing
    def _is_api(self) -> bool:
        path = urlsplit(self.path).path
        return path == API or path.startswith(API + "/")

    def do_GET(self) -> None:
        if self._is_api():
            self._api("GET")
        else:
            super().do_GET()

    def do_HEAD(self) -> None:
        if self._is_api():
            self._send_json(405, {"error": "HEAD is not served for the editor's endpoints"})
        else:
            super().do_HEAD()

    def do_POST(self) -> None:
        if self._is_api():
            self._api("POST")
        else:
            self._send_json(405, {"error": "only the editor's endpoints take a POST"})

    # ---- the editor
    def _api(self, method: str) -> None:
        url = urlsplit(self.path)
        route = url.path[len(API) :].rstrip("/")
        query = parse_qs(url.query)
        editor = self.server.editor
        try:
            if method == "GET" and route == "":
                self._send_json(200, editor.info())
                return
            if not editor.enabled:
                raise EditRefused(editor.reason, 403)
            self._check_host()
            if method == "POST":
                if route != "/save":
                    raise EditRefused(f"no endpoint POST {API}{route}", 404)
                self._check_origin()
                job = editor.save(self._read_json())
                self._send_json(202, job.public())
                return
            if route == "/asset":
                self._send_json(200, editor.state(_one(query, "id")))
            elif route == "/photo":
                self._send_bytes(200, editor.photo_png(_one(query, "id")), "image/png")
            elif route == "/mask":
                self._send_bytes(200, editor.mask_png(_one(query, "id")), "image/png")
            elif route == "/status":
                self._send_json(200, editor.status(_one(query, "job")))
            elif route == "/save":
                raise EditRefused("save with a POST", 405)
            else:
                raise EditRefused(f"no endpoint GET {API}{route}", 404)
        except EditRefused as e:
            if e.status >= 500:
                log.error("%s", e)
            self._send_json(e.status, {"error": str(e)})
        except Exception as e:  # a bug must answer, not hang the page
            log.exception("%s %s", method, url.path)
            self._send_json(500, {"error": f"{type(e).__name__}: {e}"})

    def _check_host(self) -> None:
        want = f"{EDITOR_HOST}:{self.server.server_address[1]}"
        if self.headers.get("Host", "") != want:
            raise EditRefused(
                f"the editor answers only requests to http://{want}/ (Host: "
                f"{self.headers.get('Host', '')!r})",
                403,
            )

    def _check_origin(self) -> None:
        origin = self.headers.get("Origin")
        if origin != self.server.origin:
            raise EditRefused(
                f"the editor takes saves only from its own page ({self.server.origin}), not "
                f"from origin {origin!r}",
                403,
            )
        site = self.headers.get("Sec-Fetch-Site")
        if site is not None and site != "same-origin":
            raise EditRefused(f"the editor takes saves only from its own page ({site})", 403)
        ctype = (self.headers.get("Content-Type") or "").split(";")[0].strip().lower()
        if ctype != "application/json":
            raise EditRefused("send the save as Content-Type: application/json", 415)

    def _read_json(self) -> Any:
        try:
            length = int(self.headers.get("Content-Length", ""))
        except ValueError as e:
            raise EditRefused("a save needs a Content-Length", 411) from e
        if length < 0 or length > MAX_REQUEST_BYTES:
            raise EditRefused(f"the request is larger than {MAX_REQUEST_BYTES >> 20} MiB", 413)
        body = self.rfile.read(length)
        try:
            return json.loads(body.decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as e:
            raise EditRefused(f"the request is not JSON: {e}") from e

    def _send_bytes(self, status: int, data: bytes, ctype: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(data)

    def _send_json(self, status: int, doc: Mapping[str, Any]) -> None:
        self._send_bytes(status, json.dumps(doc).encode("utf-8"), "application/json")


def _one(query: dict[str, list[str]], key: str) -> str:
    values = query.get(key) or []
    if len(values) != 1:
        raise EditRefused(f"give one {key}= in the query")
    return values[0]


class GalleryServer(ThreadingHTTPServer):
    """A threading HTTP server of OUT with its :class:`MaskEditor` (``editor``) and the
    origin its page has (``origin``)."""

    daemon_threads = True

    def __init__(
        self,
        out: Path,
        address: tuple[str, int],
        editor_overrides: Mapping[str, Any] | None = None,
    ) -> None:
        handler = functools.partial(GalleryHandler, directory=str(out.resolve()))
        super().__init__(address, handler)
        host, port = self.server_address[:2]
        self.origin = f"http://{EDITOR_HOST}:{port}"
        on = host == EDITOR_HOST
        self.editor = MaskEditor(
            out,
            enabled=on,
            reason="" if on else (
                f"the mask editor works only when the gallery is served on {EDITOR_HOST} "
                f"(this server is bound to {host}); run pact gallery OUT --serve"
            ),
            overrides=editor_overrides,
            after=functools.partial(_rewrite_page, out),
        )  # fmt: skip


def _rewrite_page(out: Path) -> None:
    write_gallery(out)


def gallery_server(
    out_dir: str | Path,
    port: int = 8000,
    host: str = "127.0.0.1",
    editor_overrides: Mapping[str, Any] | None = None,
) -> GalleryServer:
    """An HTTP server of ``out_dir`` with the mask editor (not yet serving: call
    ``serve_forever``); port 0 picks a free one (``server.server_address[1]``). Binds
    the loopback interface unless ``host`` says otherwise (the editor is then off).
    ``editor_overrides`` replace default convert settings of the editor's
    re-conversions (tests)."""
    out = Path(out_dir)
    if not out.is_dir():
        raise FileNotFoundError(f"{out}: no such output folder")
    return GalleryServer(out, (host, port), editor_overrides)


@contextlib.contextmanager
def serving(
    out_dir: str | Path,
    port: int = 0,
    host: str = "127.0.0.1",
    editor_overrides: Mapping[str, Any] | None = None,
) -> Iterator[str]:
    """Serve ``out_dir`` from a background thread while the block runs; yields its URL."""
    server = gallery_server(out_dir, port, host, editor_overrides)
    thread = threading.Thread(target=server.serve_forever, name="gallery-http", daemon=True)
    thread.start()
    try:
        yield f"http://{host}:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=5)


def serve_until_interrupted(server: ThreadingHTTPServer) -> None:
    """Serve until Ctrl-C, then close the socket."""
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m asset_pipeline.gallery.server",
        description="Write OUT/index.html; --serve serves OUT on 127.0.0.1 for its 3D views; "
        "--screenshot PNG takes a headless-Chromium shot of the served page.",
    )
    ap.add_argument("out", type=Path, help="output folder (assets, registry.sqlite)")
    ap.add_argument("--serve", action="store_true", help="serve the folder over HTTP after writing")
    ap.add_argument("--port", type=int, default=8000, help="port (0: any free one; default 8000)")
    ap.add_argument("--host", default="127.0.0.1", help="interface (default: loopback only)")
    ap.add_argument("--no-write", action="store_true", help="keep an existing index.html")
    ap.add_argument("--screenshot", type=Path, metavar="PNG", help="write a screenshot")
    ap.add_argument("--query", default="", help="page query, e.g. asset=ID&q=joint_door_0:upper")
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=2000)
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds to wait for the 3D views")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(message)s")
    try:
        if not args.no_write or not (args.out / "index.html").is_file():
            index = write_gallery(args.out)
            if not args.screenshot:
                print(index, flush=True)
        if args.screenshot:
            with serving(args.out) as url:
                page = url + "index.html" + (f"?{args.query}" if args.query else "")
                state = screenshot(
                    page, args.screenshot, args.width, args.height, timeout=args.timeout
                )
            print(args.screenshot, flush=True)
            if state != "1":
                why = "a 3D view failed" if state == "error" else "timed out"
                print(f"warning: the page was not ready ({why})", file=sys.stderr)
                return 4
            return 0
        if not args.serve:
            return 0
        server = gallery_server(args.out, args.port, args.host)
    except (FileNotFoundError, CatalogError, OSError, ScreenshotError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    host, port = server.server_address[:2]
    print(f"serving {args.out} at http://{host}:{port}/ (Ctrl-C stops)", flush=True)
    serve_until_interrupted(server)
    return 0


if __name__ == "__main__":
    sys.exit(main())
