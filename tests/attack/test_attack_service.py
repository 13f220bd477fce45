"""Attack: a request that makes a service handler fail (docs/safety.md, the attack table). Whatever
the handler does, the caller gets a reply with the reason at once, never a wait until its timeout, and
the node keeps serving (bus/service.py: one place, for every service).

- A handler that raises, and one that returns no response, in a node of its own process, called over
  real DDS: error replies with the reason, counted (`service_errors`, `Node.service_stats`).
  Checked against a broken build: bus/service.py's `_on_request` without its try/except (the
  exception left to the executor) fails it: no reply, `ServiceError: no reply ... within 10 s`.
- A 300-character name to the object memory's /object_memory/memory_file (which raised ENAMETOOLONG
  in `state_file` on Python 3.10-3.12): refused with the reason. Checked against a broken build:
  statefiles.py's name check removed: the open raises ENAMETOOLONG and the reply is a bare `cannot
  write ...: File name too long`, not the refusal with its reason that this test asks for.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

from busutil import Output, Procs, env

from go2vlm.bus.service import ServiceClient
from go2vlm.msgs.go2vlm_msgs import MemoryFile
from go2vlm.statefiles import state_dir

SERVER = """
import json, sys
from go2vlm.bus import Node
from go2vlm.msgs.go2vlm_msgs import MemoryFile

class Raising(Node):
    name = "raising"

    def __init__(self):
        super().__init__()
        self.create_service(MemoryFile, "/raising/file", self.handle)

    def handle(self, req):
        if req.command == "raise":
            raise RuntimeError("the handler broke on purpose")
        if req.command == "none":
            return None
        return MemoryFile.Response(True, "fine", 1)

node = Raising().start()
print("serving", flush=True)
sys.stdin.read()  # until the test closes stdin
print("stats " + json.dumps(node.service_stats()), flush=True)
node.shutdown()
"""


def _call(client: ServiceClient, command: str, path: str = "") -> tuple[object, float]:
    t0 = time.monotonic()
    rep = client.call(MemoryFile.Request(command=command, path=path), 10)
    return rep, time.monotonic() - t0


def test_a_raising_handler_answers_with_the_reason(procs: Procs) -> None:
    p = subprocess.Popen([sys.executable, "-c", SERVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, env=env())  # fmt: skip
    procs.procs.append(p)
    out = Output(p)
    assert out.wait_line("serving", 60), "".join(out.lines)
    spent: dict[str, float] = {}
    with ServiceClient(MemoryFile, "/raising/file") as client:
        assert client.wait_for_service(60), "no service"
        client.call(MemoryFile.Request(command="ok"), 30)  # discovery done: the timings below are the replies
        rep, spent["raise"] = _call(client, "raise")
        assert not rep.success, rep  # type: ignore[attr-defined]
        assert "RuntimeError: the handler broke on purpose" in rep.message, rep  # type: ignore[attr-defined]
        rep, spent["none"] = _call(client, "none")
        assert not rep.success and "returned NoneType" in rep.message, rep  # type: ignore[attr-defined]
        rep, _ = _call(client, "ok")
        assert rep.success and rep.message == "fine", rep  # type: ignore[attr-defined]  # it keeps serving
    assert p.stdin is not None
    p.stdin.close()
    text = out.finish(30)
    stats = json.loads(text.split("stats ", 1)[1].splitlines()[0])["/raising/file"]
    assert stats["answered"] == 4 and stats["errors"] == 2 and "NoneType" in stats["last_error"], stats
    print("a raising handler: error reply in " + ", ".join(f"{k} {v * 1000:.1f} ms" for k, v in spent.items())
          + f" (wall); counted {stats['errors']} of {stats['answered']}")  # fmt: skip


def test_a_300_character_name_is_refused_with_the_reason(procs: Procs) -> None:
    p = procs.start("run", "object_memory", "--param", "image_topic=", "--param", "scan_topic=")
    spent: dict[str, float] = {}
    with ServiceClient(MemoryFile, "/object_memory/memory_file") as client:
        assert client.wait_for_service(60), "no object memory"
        folder = state_dir() / "objects"
        for name, path, says in (("name", "a" * 300, "300 characters"),
                                 ("in its folder", str(folder / ("a" * 300)), "300 characters"),
                                 ("a long folder", "a" * 300 + "/b", "is not in")):  # fmt: skip
            for command in ("save", "load"):
                rep, spent[f"{name} {command}"] = _call(client, command, path)
                assert not rep.success and rep.message.startswith("refused"), rep  # type: ignore[attr-defined]
                assert says in rep.message, rep  # type: ignore[attr-defined]
        rep, _ = _call(client, "save", "after")
        assert rep.success, rep  # type: ignore[attr-defined]  # it keeps serving
    print("300-character names refused in " + ", ".join(f"{k} {v * 1000:.1f} ms" for k, v in spent.items())
          + " (wall)")  # fmt: skip
    assert p.poll() is None, "the object memory died"
