"""Attack: the MCP server over HTTP (docs/safety.md, the attack table; docs/mcp.md).

- DNS rebinding: a web page's request reaches the server with a foreign Host (or Origin) header: 421
  (403), before any MCP handling, on loopback and on a token bind alike.
- Token-less binds: only exactly 127.0.0.1, ::1 and localhost; 127.0.0.7 and 0:0:0:0:0:0:0:1 need the
  token. The token never comes from the command line.
- An IPv6 bind serves (the Host check names [::1]).
- A body over the limit (1 MiB, under the SDK's 4 MiB) is refused with 413.
"""

from __future__ import annotations

import re
import signal
import socket
import subprocess

import anyio
import pytest
from busutil import GO2VLM, Output, Procs, env
from mcputil import TOOLS, http_client

pytest.importorskip("mcp")

TOKEN = "attack-token-0123456789abcdef"
HEADERS = {"Content-Type": "application/json", "Accept": "application/json, text/event-stream"}
LIST = {"jsonrpc": "2.0", "id": 1, "method": "tools/list"}


def _serve(procs: Procs, bind: str, **environ: str) -> tuple[subprocess.Popen[str], str]:
    p = subprocess.Popen([*GO2VLM, "mcp", "--http", bind], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                         text=True, env={**env(), **environ})  # fmt: skip
    procs.procs.append(p)
    out = Output(p)
    assert out.wait_line("serving MCP on http://", 120), "".join(out.lines)[-3000:]
    port = re.search(r"http://\S+:(\d+)/mcp", "".join(out.lines))
    assert port is not None
    return p, port.group(1)


def _usage(*args: str, **environ: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*GO2VLM, "mcp", *args], capture_output=True, text=True, env={**env(), **environ},
                          timeout=60)  # fmt: skip


def test_token_less_only_on_the_three_loopback_names_and_never_on_the_command_line(tmp_path) -> None:
    for bind in ("127.0.0.7:0", "[0:0:0:0:0:0:0:1]:0", "0.0.0.0:0"):
        r = _usage("--http", bind)
        assert r.returncode == 2 and "needs a token" in r.stderr, (bind, r.stderr)
    r = _usage("--http", "0.0.0.0:0", "--token", TOKEN)
    assert r.returncode == 2 and "ps" in r.stderr and "--token-file" in r.stderr, r.stderr
    r = _usage("--http", "127.0.0.1:0", "--deadman", "100000")
    assert r.returncode == 2 and "--deadman" in r.stderr, r.stderr


def test_dns_rebinding_host_and_origin_are_refused(procs: Procs, tmp_path) -> None:
    token_file = tmp_path / "token"
    token_file.write_text(TOKEN + "\n")
    local, local_port = _serve(procs, "127.0.0.1:0")
    remote = subprocess.Popen([*GO2VLM, "mcp", "--http", "0.0.0.0:0", "--token-file", str(token_file)],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env())  # fmt: skip
    procs.procs.append(remote)
    out = Output(remote)
    assert out.wait_line("serving MCP on http://", 120), "".join(out.lines)[-3000:]
    remote_port = re.search(r"http://\S+:(\d+)/mcp", "".join(out.lines)).group(1)  # type: ignore[union-attr]
    found: dict[str, int] = {}

    async def main() -> None:
        import httpx2

        async with httpx2.AsyncClient() as raw:
            bearer = {"Authorization": f"Bearer {TOKEN}"}
            for name, port, auth in (("loopback", local_port, {}), ("token", remote_port, bearer)):
                url = f"http://127.0.0.1:{port}/mcp"
                r = await raw.post(url, json=LIST, headers={**HEADERS, **auth, "Host": f"evil.example:{port}"})
                found[f"{name} foreign Host"] = r.status_code
                r = await raw.post(url, json=LIST, headers={**HEADERS, **auth, "Origin": "http://evil.example"})
                found[f"{name} foreign Origin"] = r.status_code
                assert "access-control-allow-origin" not in {k.lower() for k in r.headers}
            big = b'{"jsonrpc": "2.0", "id": 3, "method": "tools/list", "x": "' + b"x" * (2 << 20) + b'"}'
            r = await raw.post(f"http://127.0.0.1:{local_port}/mcp", content=big, headers=HEADERS)
            found["2 MiB body"] = r.status_code
        async with http_client(f"http://localhost:{local_port}/mcp") as client:  # the real names still work
            assert {t.name for t in (await client.list_tools()).tools} == TOOLS
        async with http_client(f"http://127.0.0.1:{remote_port}/mcp", TOKEN) as client:
            assert {t.name for t in (await client.list_tools()).tools} == TOOLS

    anyio.run(main)
    print(f"DNS rebinding: {found}")
    assert found == {
        "loopback foreign Host": 421, "loopback foreign Origin": 403, "token foreign Host": 421,
        "token foreign Origin": 403, "2 MiB body": 413,
    }  # fmt: skip
    assert procs.stop(local, signal.SIGTERM, 20) == 143
    assert procs.stop(remote, signal.SIGTERM, 20) == 143


def _has_ipv6_loopback() -> bool:
    try:
        with socket.socket(socket.AF_INET6) as s:
            s.bind(("::1", 0))
        return True
    except OSError:
        return False


@pytest.mark.skipif(not _has_ipv6_loopback(), reason="no IPv6 loopback on this machine")
def test_an_ipv6_bind_serves(procs: Procs) -> None:
    p, port = _serve(procs, "[::1]:0")

    async def main() -> None:
        async with http_client(f"http://[::1]:{port}/mcp") as client:
            assert {t.name for t in (await client.list_tools()).tools} == TOOLS

    anyio.run(main)
    assert procs.stop(p, signal.SIGTERM, 20) == 143
