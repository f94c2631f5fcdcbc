"""``stageid serve``: the identification boards (data, estimate, compare, export) in the browser."""

from __future__ import annotations

import click

from .._errors import DataError

_LOOPBACK = ("127.0.0.1", "localhost", "::1")


@click.command(
    "serve",
    epilog="""
\b
Examples:
  stageid serve                        # records of this folder, at http://127.0.0.1:8765/
  stageid serve data/ --port 9000
  stageid serve data/ --host 0.0.0.0   # reachable from other machines: asks for the printed token
""",
)
@click.argument("folder", default=".", type=click.Path(file_okay=False))
@click.option("--port", type=click.IntRange(0, 65535), default=8765, show_default=True, help="TCP port (0: any free).")
@click.option(
    "--host", default="127.0.0.1", show_default=True, help="Address to listen on; not loopback needs a token."
)
@click.option(
    "--max-upload-mb", type=float, default=200.0, show_default=True, help="Largest upload accepted, in megabytes."
)
def serve_command(folder: str, port: int, host: str, max_upload_mb: float) -> None:
    """Serve FOLDER's records (CSV, NPZ, MAT, HDF5, FRF tables) to a local web page: look at them,
    estimate models, compare them on held-out records and export them.  Every action shows the
    equivalent stageid command and Python call.  Stop with Ctrl-C."""
    import contextvars
    import signal
    import socket
    import tempfile

    try:
        import uvicorn

        from ..app.server import create_app, new_token
    except ImportError as exc:
        raise DataError(f"stageid serve needs the app extra (pip install 'stageid[app]'); {exc}.") from None

    token = None if host in _LOOPBACK else new_token()
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
        sock.listen(128)  # so a page opened from the printed address waits instead of being refused
    except OSError as exc:
        sock.close()
        raise DataError(f"cannot listen on {host}:{port}: {exc.strerror or exc}; expected a free port.") from None
    with tempfile.TemporaryDirectory(prefix="stageid-serve-") as scratch:
        app = create_app(folder, scratch, token=token, max_upload_mb=max_upload_mb)
        shown = f"[{host}]" if ":" in host else host
        address = f"http://{shown}:{sock.getsockname()[1]}/" + (f"?token={token}" if token else "")
        click.echo(f"stageid serve: {address}  (records of {folder}; Ctrl-C stops)", err=False)
        server = uvicorn.Server(uvicorn.Config(app, log_level="warning"))
        # outside the command's output transaction (stageid.atomic): the boards' files must
        # appear as they are written, not when the server stops
        previous = signal.signal(signal.SIGTERM, _stop)  # so the scratch folder is removed on kill
        try:
            contextvars.Context().run(server.run, sockets=[sock])
        finally:
            signal.signal(signal.SIGTERM, previous)
            for session in app.state.sessions.all():  # no fit outlives the server
                for job in list(session.jobs.values()):
                    job.cancel()


def _stop(signum, frame) -> None:
    """SIGTERM ends the server like Ctrl-C does, through the cleanup of its scratch folder."""
    raise SystemExit(0)
