"""The web application of ``stageid serve``: routes of the four boards, sessions and the token.

Starlette (a small maintained ASGI toolkit) serves the page, its script and style from the
package (no network needed), and a JSON API the page calls.  Every error the package raises
becomes ``{"error": "stageid: error: ..."}`` with status 400 (the command line's one line), and
the server keeps serving.  See ``docs/guide/serve.md`` for why this stack.
"""

from __future__ import annotations

import hmac
import secrets
from pathlib import Path
from typing import Any

from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.middleware.base import BaseHTTPMiddleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, PlainTextResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from .._errors import DataError, StageIdError
from . import compare as compare_board
from .estimate import ESTIMATES, singular_values
from .jobs import Job, start_command, start_function
from .records import inspect_record, prepare_frd, prepare_time
from .sessions import SessionStore, list_records, record_path, upload_name

__all__ = ["create_app", "new_token", "SESSION_COOKIE", "SESSION_HEADER", "TOKEN_COOKIE", "DEFAULT_MAX_UPLOAD_MB"]

SESSION_COOKIE = "stageid_session"
SESSION_HEADER = "x-stageid-session"
TOKEN_COOKIE = "stageid_token"
DEFAULT_MAX_UPLOAD_MB = 200.0
STATIC = Path(__file__).with_name("static")


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


async def _refused(request: Request, exc: Exception) -> Response:
    """Bad input of any kind: the command line's one line, status 400; the server carries on."""
    return JSONResponse({"error": f"stageid: error: {_one_line(exc)}"}, status_code=400)


async def _bug(request: Request, exc: Exception) -> Response:
    return JSONResponse({"error": f"stageid: internal error: {type(exc).__name__}: {_one_line(exc)}"}, status_code=500)


def _session_key(request: Request) -> str | None:
    """The session a request belongs to: the page's per-tab header, a ``?session=`` link, or the cookie.

    The page keeps its key in the tab's own storage and sends it as a header, so two tabs of one
    browser (which share cookies) are two sessions; a request that sends the header never falls
    back to the cookie.  Plain HTTP clients use the cookie.
    """
    if SESSION_HEADER in request.headers:
        return request.headers[SESSION_HEADER]
    return request.query_params.get("session") or request.cookies.get(SESSION_COOKIE)


class _Guard(BaseHTTPMiddleware):
    """The token check (when the server listens beyond this machine) and the session of API calls."""

    async def dispatch(self, request: Request, call_next):
        config = request.app.state
        given_token = request.query_params.get("token")
        if config.token is not None:
            presented = given_token or request.cookies.get(TOKEN_COOKIE) or ""
            if not hmac.compare_digest(presented.encode(), config.token.encode()):
                return PlainTextResponse(
                    "stageid: error: this server needs the token printed when it started; open the address it "
                    "printed (with ?token=...).",
                    status_code=403,
                )
        if not request.url.path.startswith("/api/"):  # the page and its files need no session
            response = await call_next(request)
        else:
            session = config.sessions.get(_session_key(request))
            fresh = session is None
            if fresh:
                session = config.sessions.new()
            request.state.session = session
            response = await call_next(request)
            response.headers[SESSION_HEADER] = session.key
            if fresh and SESSION_HEADER not in request.headers:
                response.set_cookie(SESSION_COOKIE, session.key, httponly=True, samesite="strict")
        if config.token is not None and given_token:
            response.set_cookie(TOKEN_COOKIE, config.token, httponly=True, samesite="strict")
        return response


async def _body(request: Request) -> dict[str, Any]:
    try:
        body = await request.json()
    except ValueError:
        raise DataError("the request body is not JSON; expected an object of settings.") from None
    if not isinstance(body, dict):
        raise DataError("the request body must be a JSON object of settings.")
    return body


def _source_path(request: Request, source: str, name: str) -> Path:
    session = request.state.session
    if source == "upload":
        return record_path(session.uploads, upload_name(name))
    if source == "folder":
        return record_path(request.app.state.folder, name)
    raise DataError(f"record source must be folder or upload; got {source!r}.")


async def index(request: Request) -> Response:
    return FileResponse(STATIC / "index.html", media_type="text/html")


async def state(request: Request) -> Response:
    session = request.state.session
    return JSONResponse(
        {
            "folder": str(request.app.state.folder),
            "records": list_records(request.app.state.folder),
            "model_files": list_records(request.app.state.folder, (".json",)),
            "uploads": sorted(p.name for p in session.uploads.iterdir() if not p.name.startswith(".")),
            "max_upload_mb": request.app.state.max_upload_mb,
            "datasets": {k: {n: v for n, v in d.items() if n != "figures"} for k, d in session.datasets.items()},
            "models": session.models,
            "estimates": list(ESTIMATES),
        }
    )


async def upload(request: Request) -> Response:
    """The request body is the file; ``?name=`` its name.  Refused beyond the size limit."""
    session = request.state.session
    name = upload_name(request.query_params.get("name", ""))
    limit = int(request.app.state.max_upload_mb * 1e6)
    declared = request.headers.get("content-length")
    too_big = DataError(
        f"upload {name!r} is larger than the {request.app.state.max_upload_mb:g} MB limit of this server."
    )
    if declared is not None and declared.isdigit() and int(declared) > limit:
        return JSONResponse({"error": f"stageid: error: {too_big}"}, status_code=413)
    target = session.uploads / name
    partial = target.with_name(f".{name}.part")
    size = 0
    with open(partial, "wb") as fh:
        async for chunk in request.stream():
            size += len(chunk)
            if size > limit:
                break
            fh.write(chunk)
    if size > limit:
        partial.unlink()
        return JSONResponse({"error": f"stageid: error: {too_big}"}, status_code=413)
    try:
        ts = _sample_time(request.query_params.get("ts"))
        info = await run_in_threadpool(inspect_record, partial.rename(target), ts)
    except BaseException:
        target.unlink()  # a file the readers refuse is not kept
        raise
    return JSONResponse({"name": name, "source": "upload", **info})


def _sample_time(text: Any) -> float | None:
    """The sample time the page gives for records without a time column (empty: none)."""
    if text in (None, ""):
        return None
    try:
        return float(text)
    except (TypeError, ValueError):
        raise DataError(f"the sample time must be a number of seconds; got {text!r}.") from None


async def inspect(request: Request) -> Response:
    path = _source_path(request, request.query_params.get("source", "folder"), request.query_params.get("name", ""))
    return JSONResponse(await run_in_threadpool(inspect_record, path, _sample_time(request.query_params.get("ts"))))


async def prepare(request: Request) -> Response:
    session = request.state.session
    body = await _body(request)
    path = _source_path(request, str(body.get("source", "folder")), str(body.get("name", "")))
    settings = dict(body.get("settings") or {})
    settings["ts"] = _sample_time(settings.get("ts"))
    info = await run_in_threadpool(inspect_record, path, settings["ts"])
    out = session.next_name("d")
    if info["kind"] == "frd":
        entry = await run_in_threadpool(prepare_frd, path, session.workspace / f"{out}.csv", settings)
    else:
        entry = await run_in_threadpool(prepare_time, path, session.workspace / f"{out}.npz", settings)
    entry |= {"name": out, "from": body.get("name")}
    session.datasets[out] = entry
    return JSONResponse(entry)


def _start(request: Request, title: str, action) -> Response:
    session = request.state.session
    args, python, then = action
    job = Job(session.next_name("j"), title, python=python)
    session.jobs[job.key] = job
    if args:
        start_command(job, args, session.workspace, then)
    else:
        start_function(job, then)
    return JSONResponse(job.state())


async def estimate(request: Request) -> Response:
    session = request.state.session
    body = await _body(request)
    method = str(body.get("method", ""))
    if method not in ESTIMATES:
        raise DataError(f"estimate method must be one of {', '.join(ESTIMATES)}; got {method!r}.")
    options = dict(body.get("options") or {})
    if method == "closedloop" and options.get("controller") and options["controller"] != "unknown":
        options["controller"] = _controller_copy(request, str(options["controller"]))
    action = ESTIMATES[method](session, str(body.get("data", "")), options, session.next_name("m"))
    return _start(request, f"estimate {method}", action)


def _controller_copy(request: Request, name: str) -> str:
    """A controller model file of the served folder, copied into the session's folder; its new name."""
    path = record_path(request.app.state.folder, name)
    if path.suffix.lower() != ".json":
        raise DataError(f"the controller must be a model file (.json); got {name!r}.")
    local = f"K_{path.name}"
    (request.state.session.workspace / local).write_bytes(path.read_bytes())
    return local


async def order(request: Request) -> Response:
    session = request.state.session
    body = await _body(request)
    data, options = str(body.get("data", "")), body.get("options") or {}
    job = Job(session.next_name("j"), "singular values", python="# HankelMAP(horizon=p).fit(exp).markov_parameters()")
    session.jobs[job.key] = job
    start_function(job, lambda: singular_values(session, data, options))
    return JSONResponse(job.state())


async def compare(request: Request) -> Response:
    session = request.state.session
    body = await _body(request)
    action = compare_board.compare(
        session, str(body.get("model", "")), str(body.get("data", "")), session.next_name("c")
    )
    return _start(request, "compare", action)


async def export(request: Request) -> Response:
    session = request.state.session
    body = await _body(request)
    fmt = str(body.get("format", "json"))
    action = compare_board.export(session, str(body.get("model", "")), fmt, body.get("options") or {})
    return _start(request, f"export {fmt}", action)


def _job(request: Request) -> Job:
    job = request.state.session.jobs.get(request.path_params["key"])
    if job is None:
        raise DataError(f"no job {request.path_params['key']!r} in this session.")
    return job


async def job_state(request: Request) -> Response:
    return JSONResponse(_job(request).state())


async def job_cancel(request: Request) -> Response:
    job = _job(request)
    job.cancel()
    return JSONResponse(job.state())


async def download(request: Request) -> Response:
    data, media = compare_board.export_file(request.state.session, request.path_params["name"])
    name = request.path_params["name"]
    return Response(data, media_type=media, headers={"Content-Disposition": f'attachment; filename="{name}"'})


def create_app(
    folder: str | Path, scratch: str | Path, token: str | None = None, max_upload_mb: float = DEFAULT_MAX_UPLOAD_MB
) -> Starlette:
    """The ASGI application serving ``folder``'s records; session workspaces go under ``scratch``.

    ``token``: when given, every request must carry it (``?token=`` once, then a cookie);
    others get 403.  ``max_upload_mb``: the largest upload accepted.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise DataError(f"folder {str(folder)!r} does not exist; expected a folder of records.")
    if not max_upload_mb > 0:
        raise DataError(f"max_upload_mb must be positive; got {max_upload_mb!r}.")
    routes = [
        Route("/", index),
        Route("/api/state", state),
        Route("/api/upload", upload, methods=["POST"]),
        Route("/api/inspect", inspect),
        Route("/api/prepare", prepare, methods=["POST"]),
        Route("/api/estimate", estimate, methods=["POST"]),
        Route("/api/order", order, methods=["POST"]),
        Route("/api/compare", compare, methods=["POST"]),
        Route("/api/export", export, methods=["POST"]),
        Route("/api/jobs/{key}", job_state),
        Route("/api/jobs/{key}/cancel", job_cancel, methods=["POST"]),
        Route("/api/files/{name}", download),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
    ]
    app = Starlette(routes=routes, exception_handlers={StageIdError: _refused, OSError: _refused, Exception: _bug})
    app.add_middleware(_Guard)
    app.state.folder = folder
    app.state.token = token
    app.state.max_upload_mb = float(max_upload_mb)
    app.state.sessions = SessionStore(Path(scratch))
    return app


def new_token() -> str:
    """A random token for a server reachable from other machines."""
    return secrets.token_urlsafe(16)
