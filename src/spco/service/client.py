"""A Python client of ``spco serve`` whose calls mirror the library's ``where`` / ``what`` / ``teach``.

::

    from spco.service.client import Client

    robot = Client("http://127.0.0.1:8765")            # token="…" or token_file="…" if the server has one
    robot.what(1.2, -0.4, 1.57)["names"][0]["name"]    # 'kitchen'
    robot.where("kitchen", n=5)["positions"][0]        # {'x': …, 'y': …, 'theta': …, 'probability': …}
    robot.teach(x=1.2, y=-0.4, theta=1.57, sentence="this is the study")   # {'seq': 7, 'teachings': 7, …}

The answers are the JSON of ``spco where|what --json`` and of :class:`spco.service.LiveHome`. It
needs nothing but the standard library (and NumPy for array images): one keep-alive HTTP/1.1
connection (``http.client``), TLS for an ``https://`` address (a reverse proxy in front of the
server). An error answer raises :class:`ClientError` with the server's message and HTTP status.
"""

from __future__ import annotations

import base64
import http.client
import json
import os
import re
import ssl
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import quote, urlencode, urlsplit

from spco.errors import SpcoError

__all__ = ["DEFAULT_URL", "Client", "ClientError", "ServeProcess"]

DEFAULT_URL = "http://127.0.0.1:8765"


class ClientError(SpcoError):
    """An error answer of the server (or no server), with its HTTP ``status`` (0: no answer).

    404: an unknown place name, sample or teaching; 409: a conflicting teaching or undo; 401: a
    missing or wrong token; 422 / 400 / 413 / 415: a request with bad values; 503: the server's
    writer is gone.
    """

    def __init__(self, status: int, message: str) -> None:
        self.status = status
        self.message = message
        super().__init__(f"{message} (HTTP {status})" if status else message)


def _image_fields(image: Any, encoding: str | None) -> dict[str, Any]:
    """The JSON fields of a view: JPEG/PNG bytes or a file path, or raw pixels (a uint8 array)."""
    if image is None:
        return {}
    if isinstance(image, str | os.PathLike):
        image = Path(image).read_bytes()
    if isinstance(image, bytes | bytearray | memoryview):
        fields: dict[str, Any] = {"image": base64.b64encode(bytes(image)).decode("ascii")}
        if encoding is not None:
            raise ClientError(0, "raw pixel bytes need their shape: give a uint8 array (H, W[, 3]) instead")
        return fields
    import numpy as np

    array = np.ascontiguousarray(image)
    if array.dtype != np.uint8 or array.ndim not in (2, 3):
        raise ClientError(0, f"an image array must be uint8 (H, W) or (H, W, 3), got {array.dtype} "
                          f"{array.shape}")
    if encoding is None:
        encoding = "mono8" if array.ndim == 2 else "bgr8"
    return {"image": base64.b64encode(array.tobytes()).decode("ascii"), "encoding": encoding,
            "width": int(array.shape[1]), "height": int(array.shape[0])}


class Client:
    """A connection to ``spco serve`` at ``url``.

    Parameters
    ----------
    url: the server's address (``http://HOST:PORT``, or ``https://…`` behind a TLS proxy).
    token: the server's token, or ``token_file`` holding it (or ``$SPCO_TOKEN``).
    timeout: seconds to wait for an answer (a teaching takes tens of milliseconds).
    """

    def __init__(self, url: str = DEFAULT_URL, *, token: str | None = None, token_file: str | None = None,
                 timeout: float = 30.0) -> None:
        parts = urlsplit(url)
        if parts.scheme not in ("http", "https") or not parts.hostname:
            raise ClientError(0, f"not a server address: {url!r} (expected http://HOST:PORT)")
        self.url = url.rstrip("/")
        self._host, self._https = parts.hostname, parts.scheme == "https"
        self._port = parts.port or (443 if self._https else 80)
        self._prefix = parts.path.rstrip("/")
        if token is None and token_file is not None:
            token = Path(token_file).expanduser().read_text(encoding="utf-8").strip().splitlines()[0].strip()
        token = token or os.environ.get("SPCO_TOKEN") or None
        self._headers = {"Accept": "application/json"}
        if token:
            self._headers["Authorization"] = f"Bearer {token}"
        self.timeout = timeout
        self._connection: http.client.HTTPConnection | None = None

    # ------------------------------------------------------------------ transport
    def _connect(self) -> http.client.HTTPConnection:
        if self._connection is None:
            if self._https:
                self._connection = http.client.HTTPSConnection(self._host, self._port, timeout=self.timeout,
                                                               context=ssl.create_default_context())
            else:
                self._connection = http.client.HTTPConnection(self._host, self._port, timeout=self.timeout)
        return self._connection

    def request(self, method: str, path: str, body: dict[str, Any] | None = None) -> Any:
        """Send one request and return the decoded JSON answer; raises :class:`ClientError`.

        A GET that finds the kept-alive connection closed by the server is sent once more.
        """
        data = None if body is None else json.dumps(body, allow_nan=False).encode("utf-8")
        headers = dict(self._headers)
        if data is not None:
            headers["Content-Type"] = "application/json"
        for attempt in (0, 1):
            connection = self._connect()
            try:
                connection.request(method, self._prefix + path, body=data, headers=headers)
                response = connection.getresponse()
                payload = response.read()
                break
            except (ConnectionError, http.client.HTTPException, OSError) as exc:
                self.close()
                if attempt == 0 and method == "GET" and isinstance(
                        exc, http.client.RemoteDisconnected | ConnectionResetError | BrokenPipeError):
                    continue
                raise ClientError(0, f"no answer from {self.url}: {exc}") from None
        if response.getheader("Connection", "").lower() == "close":
            self.close()
        try:
            answer = json.loads(payload.decode("utf-8")) if payload else None
        except (UnicodeDecodeError, json.JSONDecodeError):
            answer = None
        if response.status >= 400:
            message = answer.get("error") if isinstance(answer, dict) else payload.decode("utf-8", "replace")
            raise ClientError(response.status, str(message or response.reason))
        return answer

    def close(self) -> None:
        """Close the connection (the next call opens a new one)."""
        if self._connection is not None:
            self._connection.close()
            self._connection = None

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ the library's calls
    def health(self) -> dict[str, Any]:
        """``GET /health``: ``{"status", "home", "samples", "taught", "teachings", …}``."""
        return self.request("GET", "/health")

    def where(self, name: str, n: int = 10, *, seed: int = 0) -> dict[str, Any]:
        """Poses for the place ``name`` (as :func:`spco.knowledge.where`; ``spco where --json``)."""
        return self.request("GET", "/where?" + urlencode({"name": name, "n": n, "seed": seed}))

    def what(self, x: float, y: float, theta: float, *, image: Any = None, encoding: str | None = None,
             visual: Any = None, top: int = 3) -> dict[str, Any]:
        """The ``top`` place names at pose (x, y, θ) (as :func:`spco.knowledge.what`; ``spco what --json``).

        ``image``: JPEG/PNG bytes or a file's path, or a uint8 array (H, W, 3) in ``encoding``
        ``bgr8`` (default) / ``rgb8``, or (H, W) ``mono8``; ``visual``: the view's counts instead.
        """
        if image is None and visual is None:
            return self.request("GET", "/what?" + urlencode({"x": repr(float(x)), "y": repr(float(y)),
                                                             "theta": repr(float(theta)), "top": top}))
        body: dict[str, Any] = {"x": x, "y": y, "theta": theta, "top": top, **_image_fields(image, encoding)}
        if visual is not None:
            body["visual"] = [int(v) for v in visual]
        return self.request("POST", "/what", body)

    def teach(self, *, sentence: str | None = None, id: int | None = None, x: float | None = None,
              y: float | None = None, theta: float | None = None, image: Any = None,
              encoding: str | None = None, visual: Any = None) -> dict[str, Any]:
        """Teach a sentence for sample ``id``, or a new observation at (x, y, θ) with an optional view
        (as :func:`spco.knowledge.teach`, or ``spco teach``); returns ``{"seq", "teachings", …}`` once
        the server has the teaching on disk."""
        body: dict[str, Any] = {"sentence": sentence, **_image_fields(image, encoding)}
        for key, value in (("id", id), ("x", x), ("y", y), ("theta", theta)):
            if value is not None:
                body[key] = value
        if visual is not None:
            body["visual"] = [int(v) for v in visual]
        return self.request("POST", "/teach", body)

    def ask(self, n: int = 5, *, unsure_only: bool = False) -> dict[str, Any]:
        """Where to ask "what is this place?" next (as :func:`spco.knowledge.ask`; ``spco ask --json``):
        ``{"home", "gain", "questions"}``, best first (``GET /ask``)."""
        return self.request("GET", "/ask?" + urlencode({"n": n, "unsure_only": "true" if unsure_only
                                                         else "false"}))

    def undo(self, seq: int) -> dict[str, Any]:
        """Undo teaching ``seq`` (``DELETE /teach/{seq}``)."""
        return self.request("DELETE", f"/teach/{int(seq)}")

    def regions(self) -> dict[str, Any]:
        """The learnt regions, concepts and samples (``GET /regions``)."""
        return self.request("GET", "/regions")

    def map_image(self) -> bytes:
        """The server's map image (``GET /map``: PNG or JPEG bytes); :class:`ClientError` 404 without one."""
        connection = self._connect()
        try:
            connection.request("GET", self._prefix + "/map", headers=self._headers)
            response = connection.getresponse()
            payload = response.read()
        except (ConnectionError, http.client.HTTPException, OSError) as exc:
            self.close()
            raise ClientError(0, f"no answer from {self.url}: {exc}") from None
        if response.status >= 400:
            try:
                message = json.loads(payload.decode("utf-8")).get("error")
            except (UnicodeDecodeError, json.JSONDecodeError, AttributeError):
                message = None
            raise ClientError(response.status, str(message or response.reason))
        return payload

    def revoke_sessions(self) -> int:
        """Sign every page out (``DELETE /sessions``); how many sessions were live."""
        return int(self.request("DELETE", "/sessions")["revoked"])

    def events(self, types: str | None = None) -> Iterator[dict[str, Any]]:
        """The server's events as they come (``GET /events``, Server-Sent Events), on a connection of
        their own: ``{"type": "taught" | "undone" | "answer", …}``; ``types`` e.g. ``"taught,undone"``."""
        connection = (http.client.HTTPSConnection(self._host, self._port, timeout=None,
                                                  context=ssl.create_default_context())
                      if self._https else http.client.HTTPConnection(self._host, self._port, timeout=None))
        query = "" if types is None else "?types=" + quote(types)
        try:
            connection.request("GET", self._prefix + "/events" + query,
                               headers={**self._headers, "Accept": "text/event-stream"})
            response = connection.getresponse()
            if response.status >= 400:
                raise ClientError(response.status, response.read().decode("utf-8", "replace"))
            data: list[str] = []
            for raw in response:
                line = raw.decode("utf-8").rstrip("\r\n")
                if not line:
                    if data:
                        yield json.loads("\n".join(data))
                    data = []
                elif line.startswith("data:"):
                    data.append(line[5:].strip())
        finally:
            connection.close()


#: What ``spco serve`` prints on standard error once it listens: "… at <address>/ (page), …".
_LISTENING = re.compile(r" at (https?://[^ /]+)/ \(page\)")


class ServeProcess:
    """``python -m spco serve HOME ARGS`` as a child process, started and its address read: for a
    program (a test, a benchmark, a robot's launcher) that runs a server and talks to it.

    ``args`` follow the home (e.g. ``"--port", "0", "--seed", "0"``: a free port, chosen by the
    server); ``popen`` goes to :class:`subprocess.Popen` (``env``, ``stdout``, ``preexec_fn``, …;
    standard input is closed unless given, standard error is this object's). Its standard error is
    read on a thread so the pipe never fills: :attr:`lines` holds what it printed, :attr:`url` the
    address of the line that says it listens (``http://127.0.0.1:PORT``). Raises
    :class:`ClientError` (status 0) with what it printed if it exits or ``timeout`` seconds pass
    before that line (the process is killed then).
    """

    def __init__(self, home: str | os.PathLike[str], *args: str, timeout: float = 120.0,
                 **popen: Any) -> None:
        popen.setdefault("stdin", subprocess.DEVNULL)
        self.process = subprocess.Popen([sys.executable, "-m", "spco", "serve", os.fspath(home), *args],
                                        stderr=subprocess.PIPE, text=True, **popen)
        self.lines: list[str] = []
        self.url = ""
        listening = threading.Event()

        def read() -> None:
            for line in self.process.stderr or ():
                self.lines.append(line)
                match = _LISTENING.search(line)
                if match and not listening.is_set():
                    self.url = match.group(1)
                    listening.set()
            listening.set()  # it exited before it listened

        self._reader = threading.Thread(target=read, daemon=True)
        self._reader.start()
        if not listening.wait(timeout) or not self.url:
            self.kill()
            raise ClientError(0, "spco serve did not start:\n" + self.output)

    @property
    def output(self) -> str:
        """What the server printed on standard error so far."""
        return "".join(self.lines)

    def join(self, timeout: float = 5.0) -> None:
        """Wait (at most ``timeout`` seconds) for the reader of its standard error, once it exited."""
        self._reader.join(timeout)

    def kill(self) -> None:
        """``kill -9`` if it still runs, and wait for it: no chance to clean up."""
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait(30)
        self.join()
