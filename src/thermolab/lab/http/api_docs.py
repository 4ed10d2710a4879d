"""The API docs pages (``/docs``: Swagger UI, ``/redoc``: ReDoc), served from the package.

FastAPI's own pages load their scripts from a CDN, which would run third-party
code on the lab's origin, and start Swagger UI with an inline script, which
the lab's Content-Security-Policy forbids. Here the assets come from the
``fastapi-offline`` package (it ships Swagger UI and ReDoc bundles; a
well-kept PyPI package, so no vendored copy to update by hand), and the pages
are our own: Swagger UI is started by a small script served by the lab.
"""

from __future__ import annotations

import html
import importlib.util
from pathlib import Path

from fastapi import FastAPI
from fastapi.responses import HTMLResponse, Response
from fastapi.staticfiles import StaticFiles

__all__ = ["ASSETS_URL", "install_api_docs"]

ASSETS_URL = "/docs/assets"


def _assets_dir() -> Path:
    spec = importlib.util.find_spec("fastapi_offline")
    if spec is None or spec.origin is None:  # pragma: no cover - a declared dependency
        raise RuntimeError("fastapi-offline is not installed; pip install fastapi-offline")
    return Path(spec.origin).parent / "static"


def _page(title: str, head: str, body: str) -> str:
    return (
        '<!doctype html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(title)}</title>"
        f'<link rel="icon" href="{ASSETS_URL}/favicon.png">{head}</head>'
        f"<body>{body}</body></html>\n"
    )


def install_api_docs(app: FastAPI, openapi_url: str = "/openapi.json") -> None:
    """Serve ``/docs`` and ``/redoc`` (and their assets) from the package.

    The app must be built with ``docs_url=None, redoc_url=None``.
    """
    app.mount(ASSETS_URL, StaticFiles(directory=_assets_dir()), name="api-docs-assets")
    swagger = _page(
        f"{app.title} - API",
        f'<link rel="stylesheet" href="{ASSETS_URL}/swagger-ui.css">',
        '<div id="swagger-ui"></div>'
        f'<script src="{ASSETS_URL}/swagger-ui-bundle.js"></script>'
        '<script src="/docs/start.js"></script>',
    )
    start = (
        "// Starts Swagger UI (an external script: the lab's CSP allows no inline script).\n"
        f"window.ui = SwaggerUIBundle({{url: {openapi_url!r}, dom_id: '#swagger-ui', "
        "deepLinking: true, presets: [SwaggerUIBundle.presets.apis], "
        "layout: 'BaseLayout'});\n"
    )
    redoc = _page(
        f"{app.title} - API",
        "",
        f'<redoc spec-url="{html.escape(openapi_url)}"></redoc>'
        f'<script src="{ASSETS_URL}/redoc.standalone.js"></script>',
    )

    @app.get("/docs", include_in_schema=False)
    def swagger_page() -> HTMLResponse:
        return HTMLResponse(swagger)

    @app.get("/docs/start.js", include_in_schema=False)
    def swagger_start() -> Response:
        return Response(start, media_type="text/javascript")

    @app.get("/redoc", include_in_schema=False)
    def redoc_page() -> HTMLResponse:
        return HTMLResponse(redoc)
