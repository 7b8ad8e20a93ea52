"""A meshcat server that listens on the loopback interface only, and clients that time out.

:class:`MeshcatServer` runs meshcat's ZeroMQ bridge in a subprocess whose web
server is bound to 127.0.0.1 (the stock one listens on every interface),
answers only requests whose Host header is a loopback name with its port (403
otherwise, against DNS rebinding), and stops it on close, at exit, on SIGTERM
or when this process dies.
:func:`connect` returns a ``meshcat.Visualizer`` whose calls time out, so a
dead server raises :class:`~youbot_opt.exceptions.ViewerError`; see
docs/design.md, "Module notes".

>>> with MeshcatServer() as server: vis = connect(server.zmq_url)  # doctest: +SKIP
"""

from __future__ import annotations

import atexit
import io
import logging
import os
import selectors
import signal
import subprocess
import sys
import tempfile
import threading
import time
import types
import webbrowser
from typing import IO, Any

import meshcat
import umsgpack
import zmq
from meshcat.commands import CaptureImage

from youbot_opt.exceptions import ParameterError, ViewerError

__all__ = ["LOOPBACK", "MeshcatServer", "connect"]

logger = logging.getLogger(__name__)

#: The only address the server binds to.
LOOPBACK = "127.0.0.1"

_DEFAULT_TIMEOUT = 10.0  # [s] for a request to the server, or for the server to start

# Runs in the server subprocess (``python -c``): only meshcat and tornado are
# imported there, not youbot_opt. The bridge is meshcat's own; only the web
# application's ``listen`` is pinned to the loopback address (meshcat's
# ``find_available_port`` still scans for a free port from 7000, and the ZeroMQ
# socket is bound to ``tcp://127.0.0.1`` from 6000 on by meshcat itself).
_SERVER_SCRIPT = r"""
import os, sys, threading
import tornado.web
from meshcat.servers import zmqserver as z

HOST = sys.argv[1]

class LoopbackApplication(tornado.web.Application):
    # Requests (and WebSocket upgrades) must name this server by a loopback
    # name and its port: a page of another site whose name a DNS-rebinding
    # attack points at 127.0.0.1 sends its own name as Host, and gets 403.
    allowed_hosts = frozenset()

    def listen(self, port, address=None, **kwargs):
        self.allowed_hosts = frozenset(
            f"{name}:{port}" for name in ("127.0.0.1", "localhost", "[::1]")
        )
        return super().listen(port, HOST, **kwargs)

    def find_handler(self, request, **kwargs):
        if request.headers.get("Host", "").strip().lower() not in self.allowed_hosts:
            return self.get_handler_delegate(
                request, tornado.web.ErrorHandler, {"status_code": 403}
            )
        return super().find_handler(request, **kwargs)

class LoopbackBridge(z.ZMQWebSocketBridge):
    def make_app(self):
        return LoopbackApplication([
            (r"/static/(.*)", z.StaticFileHandlerNoCache,
             {"path": z.VIEWER_ROOT, "default_filename": z.VIEWER_HTML}),
            (r"/", z.WebSocketHandler, {"bridge": self}),
        ])

def exit_with_parent():
    # The parent holds our stdin open for as long as it lives.
    while sys.stdin.buffer.read(65536):
        pass
    os._exit(0)

bridge = LoopbackBridge(host=HOST)
threading.Thread(target=exit_with_parent, daemon=True).start()
print("zmq_url=" + bridge.zmq_url, flush=True)
print("web_url=" + bridge.web_url, flush=True)
os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
bridge.run()
"""


class MeshcatServer:
    """A meshcat server subprocess bound to 127.0.0.1, stopped when no longer needed.

    Parameters
    ----------
    timeout : float
        Time in [s] to wait for the server to start, and default request
        time-out of the clients made by :meth:`visualizer`.

    Attributes
    ----------
    zmq_url : str
        ZeroMQ address of the server (``tcp://127.0.0.1:<port>``).
    web_url : str
        Address to open in a browser (``http://127.0.0.1:<port>/static/``).
    pid : int
        Process id of the server.

    Raises
    ------
    ViewerError
        If the server does not start within ``timeout`` or reports an address
        that is not on the loopback interface.

    Examples
    --------
    >>> with MeshcatServer() as server:  # doctest: +SKIP
    ...     vis = server.visualizer()
    ...     vis["box"].set_object(meshcat.geometry.Box([0.1, 0.1, 0.1]))
    """

    def __init__(self, *, timeout: float = _DEFAULT_TIMEOUT) -> None:
        if not timeout > 0:
            raise ParameterError(
                f"timeout must be > 0 [s], got {timeout!r}", name="timeout", value=timeout
            )
        self.timeout = float(timeout)
        self._closed = False
        self._sigterm: tuple[Any, Any] | None = None
        self._stderr: IO[bytes] = tempfile.TemporaryFile()
        self._process = subprocess.Popen(
            [sys.executable, "-u", "-c", _SERVER_SCRIPT, LOOPBACK],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self._stderr,
            start_new_session=True,  # Ctrl-C in a terminal or notebook does not kill it
        )
        self.pid: int = self._process.pid
        atexit.register(self.close)
        self._install_sigterm_handler()
        try:
            self.zmq_url, self.web_url = self._read_urls()
            for url in (self.zmq_url, self.web_url):
                if f"//{LOOPBACK}:" not in url:
                    raise ViewerError(
                        f"meshcat server reported {url!r}, not an address on {LOOPBACK}",
                        url=url,
                    )
        except BaseException:
            self.close()
            raise
        logger.info(
            "meshcat server %d listening on %s (web %s)", self.pid, self.zmq_url, self.web_url
        )

    def _read_urls(self) -> tuple[str, str]:
        """Read the two address lines the server prints, within ``self.timeout``."""
        stdout = self._process.stdout
        if stdout is None:  # Popen(stdout=PIPE) always sets it
            raise ViewerError("meshcat server started without an output pipe")
        buffer = b""
        deadline = time.monotonic() + self.timeout
        with selectors.DefaultSelector() as selector:
            selector.register(stdout, selectors.EVENT_READ)
            while buffer.count(b"\n") < 2:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise ViewerError(
                        f"meshcat server did not start within {self.timeout} s; "
                        f"its error output: {self._stderr_tail()!r}"
                    )
                if selector.select(remaining):
                    chunk = os.read(stdout.fileno(), 4096)
                    if not chunk:
                        self._process.wait(timeout=self.timeout)
                        raise ViewerError(
                            "meshcat server exited during start-up with code "
                            f"{self._process.returncode}; its error output: {self._stderr_tail()!r}"
                        )
                    buffer += chunk
        lines = dict(line.split("=", 1) for line in buffer.decode().splitlines() if "=" in line)
        if "zmq_url" not in lines or "web_url" not in lines:
            raise ViewerError(f"meshcat server printed {buffer!r}, not its zmq_url and web_url")
        return lines["zmq_url"].strip(), lines["web_url"].strip()

    def _stderr_tail(self, n_bytes: int = 2000) -> str:
        self._stderr.seek(0)
        return self._stderr.read().decode(errors="replace")[-n_bytes:]

    def _install_sigterm_handler(self) -> None:
        """Stop the server on SIGTERM, then hand the signal to the previous handler."""
        if threading.current_thread() is not threading.main_thread():
            logger.debug("not in the main thread: no SIGTERM handler for server %d", self.pid)
            return
        previous = signal.getsignal(signal.SIGTERM)

        def on_sigterm(signum: int, frame: types.FrameType | None) -> None:
            self.close()
            if callable(previous):
                previous(signum, frame)
            elif previous != signal.SIG_IGN:  # SIG_DFL, or a handler not set from Python
                signal.signal(signum, signal.SIG_DFL)
                os.kill(os.getpid(), signum)

        signal.signal(signal.SIGTERM, on_sigterm)
        self._sigterm = (on_sigterm, previous)

    @property
    def running(self) -> bool:
        """Whether the server process is alive."""
        return self._process.poll() is None

    def visualizer(self, *, timeout: float | None = None) -> meshcat.Visualizer:
        """Return a new client of this server.

        Parameters
        ----------
        timeout : float, optional
            Request time-out in [s]; the server's ``timeout`` when omitted.

        Returns
        -------
        meshcat.Visualizer
            A client whose calls raise :class:`ViewerError` after ``timeout``.
        """
        timeout = self.timeout if timeout is None else timeout
        return _client(self.zmq_url, timeout=timeout, web_url=self.web_url, server=None)

    def close(self) -> None:
        """Stop the server (SIGTERM, then SIGKILL after ``timeout``) and release its resources.

        Safe to call more than once.
        """
        if self._closed:
            return
        self._closed = True
        atexit.unregister(self.close)
        if self._sigterm is not None and threading.current_thread() is threading.main_thread():
            handler, previous = self._sigterm
            if signal.getsignal(signal.SIGTERM) is handler:
                signal.signal(signal.SIGTERM, previous if previous is not None else signal.SIG_DFL)
        if self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(timeout=self.timeout)
            except subprocess.TimeoutExpired:
                logger.warning("meshcat server %d ignored SIGTERM; killing it", self.pid)
                self._process.kill()
                self._process.wait()
        for stream in (self._process.stdin, self._process.stdout, self._stderr):
            if stream is not None:
                stream.close()
        logger.info("meshcat server %d stopped", self.pid)

    def __enter__(self) -> MeshcatServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "running" if self.running else "stopped"
        return f"MeshcatServer(pid={self.pid}, zmq_url={getattr(self, 'zmq_url', None)!r}, {state})"


class _TimeoutWindow:
    """Duck-types meshcat's ``ViewerWindow``, with time-outs and an optional owned server."""

    def __init__(
        self, zmq_url: str, *, timeout: float, web_url: str | None, server: MeshcatServer | None
    ) -> None:
        self.zmq_url = zmq_url
        self.timeout = timeout
        self.server = server
        self._socket: Any = None
        self._connect()
        self.web_url = web_url if web_url is not None else self._request([b"url"]).decode()
        if web_url is None:
            # As meshcat's own ViewerWindow does: a fresh socket after asking for the URL.
            self._connect()

    def _connect(self) -> None:
        if self._socket is not None:
            self._socket.close(linger=0)
        millis = max(1, round(1000 * self.timeout))
        self._socket = zmq.Context.instance().socket(zmq.REQ)
        self._socket.setsockopt(zmq.RCVTIMEO, millis)
        self._socket.setsockopt(zmq.SNDTIMEO, millis)
        self._socket.setsockopt(zmq.LINGER, 0)
        self._socket.connect(self.zmq_url)

    def _request(self, frames: list[bytes], timeout: float | None = None) -> bytes:
        if self._socket is None:
            raise ViewerError(f"the connection to {self.zmq_url} is closed", url=self.zmq_url)
        if timeout is not None:
            self._socket.setsockopt(zmq.RCVTIMEO, max(1, round(1000 * timeout)))
        try:
            self._socket.send_multipart(frames)
            reply: bytes = self._socket.recv()
        except zmq.Again as e:
            self._connect()  # a REQ socket that missed its reply cannot be reused
            raise ViewerError(
                f"meshcat server at {self.zmq_url} did not answer within "
                f"{self.timeout if timeout is None else timeout} s; is it still running? "
                "Start one with youbot_opt.viz.MeshcatServer() or `meshcat-server`.",
                url=self.zmq_url,
            ) from e
        except zmq.ZMQError as e:
            raise ViewerError(f"meshcat server at {self.zmq_url}: {e}", url=self.zmq_url) from e
        finally:
            if timeout is not None and self._socket is not None:
                self._socket.setsockopt(zmq.RCVTIMEO, max(1, round(1000 * self.timeout)))
        if reply.startswith(b"error"):
            raise ViewerError(
                f"meshcat server at {self.zmq_url} replied {reply!r}", url=self.zmq_url
            )
        return reply

    def send(self, command: Any) -> None:
        data = command.lower()
        self._request([data["type"].encode(), data["path"].encode(), umsgpack.packb(data)])

    def get_scene(self) -> str:
        return self._request([b"get_scene"]).decode()

    def get_image(self) -> Any:
        """Capture the viewer as a PIL image; needs a browser showing it (else times out)."""
        from PIL import Image

        data = CaptureImage().lower()
        try:
            reply = self._request([data["type"].encode(), b"", umsgpack.packb(data)])
        except ViewerError as e:
            raise ViewerError(
                f"{e} (get_image also needs a browser showing {self.web_url}: the browser "
                "renders the image)",
                url=self.zmq_url,
            ) from e
        try:
            return Image.open(io.BytesIO(reply))
        except OSError as e:
            raise ViewerError(
                f"meshcat server at {self.zmq_url} sent {len(reply)} bytes that are not an image",
                url=self.zmq_url,
            ) from e

    def wait(self, timeout: float | None = None) -> str:
        """Block until a browser is connected, at most ``timeout`` [s] (the default time-out)."""
        return self._request([b"wait"], timeout=timeout).decode()

    def open(self) -> _TimeoutWindow:
        webbrowser.open(self.web_url, new=2)
        return self

    def close(self) -> None:
        if self._socket is not None:
            self._socket.close(linger=0)
            self._socket = None
        if self.server is not None:
            self.server.close()


def _client(
    zmq_url: str, *, timeout: float, web_url: str | None, server: MeshcatServer | None
) -> meshcat.Visualizer:
    if not timeout > 0:
        raise ParameterError(
            f"timeout must be > 0 [s], got {timeout!r}", name="timeout", value=timeout
        )
    try:
        window = _TimeoutWindow(zmq_url, timeout=timeout, web_url=web_url, server=server)
    except BaseException:
        if server is not None:
            server.close()
        raise
    return meshcat.Visualizer(window=window)


def connect(zmq_url: str | None = None, *, timeout: float = _DEFAULT_TIMEOUT) -> meshcat.Visualizer:
    """Connect to a meshcat server, or start a private loopback one.

    Parameters
    ----------
    zmq_url : str, optional
        ZeroMQ address of a running server, e.g. ``"tcp://127.0.0.1:6000"``.
        When omitted, a :class:`MeshcatServer` is started; it belongs to the
        returned client and stops with ``visualizer.close()``.
    timeout : float
        Request time-out in [s].

    Returns
    -------
    meshcat.Visualizer
        The client; ``visualizer.url()`` is the address to open in a browser.

    Raises
    ------
    ViewerError
        If the server does not answer within ``timeout``.
    """
    if zmq_url is not None:
        return _client(zmq_url, timeout=timeout, web_url=None, server=None)
    server = MeshcatServer(timeout=timeout)
    return _client(server.zmq_url, timeout=timeout, web_url=server.web_url, server=server)
