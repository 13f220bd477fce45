"""`go2vlm objects`: what the robot remembers, where each thing is, and the memory kept between runs.

    go2vlm objects                          the running object memory's objects (/objects, latched)
    go2vlm objects --where "blue cylinder"  ask it: /object_memory/where_is
    go2vlm objects --save home              it writes its memory to a file (on its machine), the map too
    go2vlm objects --save home --overwrite  ... replacing the ones saved before
    go2vlm objects --load home              it loads a memory file, all or nothing
                                            (with a map node: the map beside it too, home.map.npz)
    go2vlm objects --file runs/goal-.../objects.json [--where X]   a saved memory, no robot needed

Like `ros2 topic echo /objects`, but readable: one line per object, the most confident first, with
its label, place in the memory's frame (odom), confidence and age (seconds between its last sighting
and the newest answer the memory has taken in).

Where the files live: the memory writes and reads only in go2vlm's state directory on its machine,
$XDG_STATE_HOME/go2vlm (~/.local/state/go2vlm without XDG_STATE_HOME). A name ("home" or "home.json")
is the file objects/home.json there; a path must lie under that directory; anything else (another
folder, `..`, a symlink leading out) is refused and nothing is written. --save never replaces a file
unless --overwrite. --file reads any file here, without a robot.

Exit codes: 0; 1 when no object memory answers within --timeout, or --where finds nothing; 2 for a
memory file that is corrupt, of another world or frame, or of a newer version, and for a file name
refused (outside the state directory, or --save over an existing file without --overwrite): one line,
nothing loaded or written. Time here is wall time: a tool's deadlines are for the person at the terminal.
"""

from __future__ import annotations

import argparse
import json
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

from go2vlm.cli.args import positive
from go2vlm.errors import ConfigError, UsageError

if TYPE_CHECKING:
    from go2vlm.msgs.go2vlm_msgs import MemoryFile_Request, MemoryFile_Response


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "objects", help="what the robot remembers and where (the object memory)", description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    p.add_argument("--where", metavar="LABEL", default=None, help='ask where something is, e.g. "blue cylinder"')
    what = p.add_mutually_exclusive_group()
    what.add_argument(
        "--save",
        metavar="NAME",
        help="the running memory writes itself to NAME: a name (saved as "
        "$XDG_STATE_HOME/go2vlm/objects/NAME.json) or a path under $XDG_STATE_HOME/go2vlm",
    )
    what.add_argument(
        "--load",
        metavar="NAME",
        help="the running memory loads NAME (a name or a path under $XDG_STATE_HOME/go2vlm; all or nothing)",
    )
    p.add_argument("--overwrite", action="store_true", help="--save: replace an existing file")
    what.add_argument("--file", metavar="FILE", type=Path, help="read a saved memory file instead of a robot")
    p.add_argument("--json", action="store_true", help="the objects as JSON")
    p.add_argument("--timeout", type=positive, default=5.0, help="seconds to wait for the object memory")
    p.set_defaults(func=cmd_objects)


def _rows(objects: list[Any], newest: float) -> list[dict[str, Any]]:
    rows = [
        {"id": o.id, "label": o.label, "x": round(o.x, 3), "y": round(o.y, 3), "confidence": round(o.confidence, 3),
         "age_s": round(max(0.0, newest - o.last_seen), 1)}
        for o in objects
    ]  # fmt: skip
    return sorted(rows, key=lambda r: (-r["confidence"], r["id"]))


def _print(rows: list[dict[str, Any]], as_json: bool, frame: str) -> None:
    if as_json:
        print(json.dumps(rows, ensure_ascii=False))
        return
    if not rows:
        print("(nothing remembered)")
        return
    print(f"{'id':<22} {'label':<18} {'x':>7} {'y':>7}  {'confidence':>10}  {'age':>7}   ({frame})")
    for r in rows:
        print(f"{r['id']:<22} {r['label']:<18} {r['x']:>7.2f} {r['y']:>7.2f}  {r['confidence']:>10.2f}  "
              f"{r['age_s']:>6.1f}s")  # fmt: skip


def _from_file(args: argparse.Namespace) -> int:
    from go2vlm.statefiles import read_bounded
    from go2vlm.world.memory import ObjectMemory
    from go2vlm.world.memory_file import MAX_FILE_BYTES, MemoryFileError, header, loads

    try:
        text = read_bounded(args.file, MAX_FILE_BYTES)
    except OSError as exc:
        raise ConfigError(f"cannot read {args.file}: {exc.strerror or exc}") from None
    try:
        objs = loads(text, None, None, 1_000_000)
    except MemoryFileError as exc:
        raise ConfigError(f"{args.file}: {exc}") from None
    world, frame = header(text)
    memory = ObjectMemory()
    memory.load(objs)
    newest = max((o.last_seen for o in objs), default=0.0)
    if args.where is not None:
        fits = memory.where_is(args.where)
        if not fits:
            print(f"{args.file} (world {world!r}) remembers no {args.where}")
            return 1
        o = fits[0]
        print(f"{o.label} at ({o.x:.2f}, {o.y:.2f}) m in {frame}, +-{o.sigma:.2f} m, confidence {o.confidence:.2f}, "
              f"seen {o.seen} times")  # fmt: skip
        return 0
    if not args.json:
        print(f"{args.file}: world {world!r}, {len(objs)} object(s)")
    _print(_rows(objs, newest), args.json, frame)
    return 0


def cmd_objects(args: argparse.Namespace) -> int:
    if args.file is not None:
        return _from_file(args)
    from go2vlm.bus import Node, interrupt_on_signals
    from go2vlm.bus.service import ServiceClient, ServiceError
    from go2vlm.bus.topics import MEMORY_FILE_SERVICE, OBJECTS, WHERE_IS_SERVICE
    from go2vlm.msgs.go2vlm_msgs import MemoryFile, WhereIs
    from go2vlm.msgs.vision_msgs import Detection3DArray
    from go2vlm.world.objects_msg import remembered

    interrupt_on_signals()
    if args.save is not None or args.load is not None:
        if args.load is not None:
            _check_local(args.load)
        command, path = ("save", args.save) if args.save is not None else ("load", args.load)
        wire = _wire_path(path)
        with ServiceClient(MemoryFile, MEMORY_FILE_SERVICE) as client, MapFiles(wire) as maps:
            if command == "load":
                maps.call("check", args.timeout)  # a bad map file: nothing is loaded, the memory neither
            try:
                req = MemoryFile.Request(command=command, path=wire, overwrite=args.overwrite)
                rep = client.call(req, args.timeout)
            except ServiceError as exc:
                raise RuntimeError(f"no object memory answers: {exc}") from None
            if not rep.success:
                raise ConfigError(rep.message)
            print(rep.message)
            said = maps.call(command, args.timeout, args.overwrite)
        if said:
            print(said)
        return 0
    if args.where is not None:
        with ServiceClient(WhereIs, WHERE_IS_SERVICE) as where_client:
            try:
                answer = where_client.call(WhereIs.Request(label=args.where), args.timeout)
            except ServiceError as exc:
                raise RuntimeError(f"no object memory answers: {exc}") from None
        if args.json:
            rows = [r for r in map(remembered, answer.objects) if r is not None]
            print(json.dumps([{"id": r.id, "label": r.label, "x": r.x, "y": r.y, "confidence": r.confidence}
                              for r in rows], ensure_ascii=False))  # fmt: skip
        else:
            print(answer.message)
        return 0 if answer.found else 1
    got: list[Detection3DArray] = []
    event = threading.Event()

    def on_objects(msg: Detection3DArray) -> None:
        got.append(msg)
        event.set()

    node = Node(node_name="_go2vlm_objects", parameter_services=False)
    OBJECTS.subscription(node, on_objects)
    node.start()
    try:
        if not event.wait(args.timeout):
            waited = f"waited {args.timeout:g} s"
            raise RuntimeError(f"no object memory publishes {OBJECTS.name} ({waited}): is one running?")
    finally:
        node.shutdown()
    msg = got[-1]
    objs = [r for r in map(remembered, msg.detections) if r is not None]
    _print(_rows(objs, msg.header.stamp.to_sec()), args.json, msg.header.frame_id)
    return 0


def _wire_path(text: str) -> str:
    """A name goes as it is (the memory's machine places it); a path, made absolute here."""
    if "/" not in text and not text.startswith("~"):
        return text
    return str(Path(text).expanduser().resolve())


class MapFiles:
    """The map node's file beside the memory's (world/map_file.py: home.json -> home.map.npz), saved
    and loaded with it: checked before the memory loads, so that a bad map file loads nothing. Without
    a map node the memory's file goes alone."""

    def __init__(self, path: str) -> None:
        from go2vlm.bus.service import ServiceClient
        from go2vlm.bus.topics import MAP_FILE_SERVICE
        from go2vlm.msgs.go2vlm_msgs import MemoryFile

        self.path = path
        self.client: ServiceClient[MemoryFile_Request, MemoryFile_Response]
        self.client = ServiceClient(MemoryFile, MAP_FILE_SERVICE)

    def __enter__(self) -> MapFiles:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.client.close()

    def call(self, command: str, timeout: float, overwrite: bool = False) -> str:
        """What the map node did ('' when none answers); ConfigError when it refused."""
        from go2vlm.bus.service import ServiceError
        from go2vlm.msgs.go2vlm_msgs import MemoryFile

        if not self.client.wait_for_service(min(timeout, 2.0)):
            return "(no map node: the memory's file alone)" if command != "check" else ""
        try:
            req = MemoryFile.Request(command=command, path=self.path, overwrite=overwrite)
            rep = self.client.call(req, timeout)
        except ServiceError as exc:
            raise RuntimeError(f"the map node does not answer: {exc}") from None
        if not rep.success:
            raise ConfigError(rep.message + (" (nothing loaded)" if command == "check" else ""))
        return str(rep.message)


def _check_local(text: str) -> None:
    """A file here that is no memory file is refused before the memory is asked (its world and frame
    are the running memory's to check)."""
    from go2vlm.statefiles import StateFileError, read_bounded, state_file
    from go2vlm.world.memory_file import MAX_FILE_BYTES, STATE_KIND, MemoryFileError, loads

    try:
        path = state_file(_wire_path(text), STATE_KIND)
    except StateFileError:
        return  # the memory refuses it, with the reason
    if not path.exists():
        return  # perhaps a file on the memory's machine: it says
    try:
        loads(read_bounded(path, MAX_FILE_BYTES), None, None, 1_000_000)
    except MemoryFileError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    except OSError as exc:
        raise UsageError(f"cannot read {path}: {exc.strerror or exc}") from None
