"""``transformers serve`` of a local checkpoint on loopback: a real OpenAI-compatible server for tests
and benchmarks of the openai backend; and a proxy in front of any server that answers every request
only after a delay (a slow model, a far GPU box)."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

__all__ = ["ServeFailed", "delaying_proxy", "free_port", "serve_checkpoint"]


class ServeFailed(RuntimeError):
    """The server exited or never became healthy; the message ends with its log's tail."""


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _serve_command() -> list[str]:
    exe = Path(sys.executable).with_name("transformers")
    if exe.exists():
        return [str(exe), "serve"]
    found = shutil.which("transformers")
    if found:
        return [found, "serve"]
    return [sys.executable, "-c", "from transformers.cli.transformers import main; main()", "serve"]


@contextmanager
def serve_checkpoint(ckpt: str | os.PathLike[str], log_path: Path, *, timeout_s: float = 120.0) -> Iterator[str]:
    """Start ``transformers serve <ckpt>`` on 127.0.0.1 and a free port, CPU, offline; yield its ``/v1`` URL
    once ``/health`` answers 200; stop it on exit. Requests must name the model ``str(ckpt)``."""
    port = free_port()
    env = dict(os.environ)
    # Offline: the server must never try the hub for a local directory.
    env.update(HF_HUB_OFFLINE="1", TRANSFORMERS_OFFLINE="1", TOKENIZERS_PARALLELISM="false")
    cmd = [*_serve_command(), str(ckpt), "--host", "127.0.0.1", "--port", str(port), "--device", "cpu"]
    with open(log_path, "w") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
    base = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + timeout_s
        while True:
            if proc.poll() is not None:
                raise ServeFailed(f"transformers serve exited {proc.returncode}:\n{log_path.read_text()[-3000:]}")
            try:
                with urllib.request.urlopen(base + "/health", timeout=2) as r:
                    if r.status == 200:
                        break
            except OSError:
                pass
            if time.monotonic() > deadline:
                tail = log_path.read_text()[-3000:]
                raise ServeFailed(f"transformers serve not healthy in {timeout_s:.0f} s:\n{tail}")
            time.sleep(0.3)  # poll interval of the health check
        yield base + "/v1"
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@contextmanager
def delaying_proxy(upstream: str, delay_s: float) -> Iterator[str]:
    """An HTTP proxy on 127.0.0.1 in front of `upstream` (a base URL such as http://127.0.0.1:8000/v1)
    that holds every request `delay_s` seconds (wall time: what a slow server costs) before it forwards
    it, then returns the whole upstream answer (a streamed one too, at once). Yields its base URL, with
    the same path as `upstream`."""
    scheme_host, _, path = upstream.partition("//")[2].partition("/")
    origin = upstream[: upstream.index("//") + 2] + scheme_host

    class Handler(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def _forward(self) -> None:
            body = self.rfile.read(int(self.headers.get("Content-Length") or 0))
            time.sleep(delay_s)  # wall time: the delay a slow server adds
            keep = {k: v for k, v in self.headers.items() if k.lower() not in ("host", "content-length", "connection")}
            req = urllib.request.Request(origin + self.path, data=body or None, headers=keep, method=self.command)
            try:
                with urllib.request.urlopen(req, timeout=600) as r:
                    status, ctype, data = r.status, r.headers.get("Content-Type", ""), r.read()
            except urllib.error.HTTPError as exc:
                status, ctype, data = exc.code, exc.headers.get("Content-Type", ""), exc.read()
            self.send_response(status)
            if ctype:
                self.send_header("Content-Type", ctype)
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)

        do_GET = do_POST = _forward

        def log_message(self, *args: object) -> None:  # quiet
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, name="delaying_proxy", daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/{path}"
    finally:
        server.shutdown()
        server.server_close()
