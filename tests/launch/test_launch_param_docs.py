"""Every documented parameter default is the code's: what a node's contract (its module docstring) and
docs/*.md say a parameter defaults to, against the node's Config dataclass.

What counts as a documented default:
- in a node's docstring, one of its parameters followed by a value in brackets: `rate_hz (50 Hz)`,
  ``margin`` (0.3 m), `release_token ("RELEASE")`, `period_s (5 s by default)`;
- in docs/*.md, a parameter in backticks followed by a value in brackets (`` `stop_distance_m` (0.8 m) ``),
  and the `default` column of a table that lists parameters in its first column (`| name | default |`).
A value is a number (with a unit: s, m, Hz, m/s, rad/s, %, ...), true or false, a quoted string or a
topic, then a closing bracket, `;`, `,` or "default" (`(true: ...)` says what a value does). A
parameter several nodes declare with different defaults belongs to the node last named (in
backticks) before it in the same paragraph; a table's parameters to the one node that has them all.
"""

from __future__ import annotations

import dataclasses
import importlib
import re
from pathlib import Path
from typing import Any

import pytest
import yaml

from go2vlm.launch.registry import NODES

DOCS = Path(__file__).resolve().parents[2] / "docs"
UNITS = r"(?:m/s\^2|m/s|rad/s\^2|rad/s|rad|ms|s|m|Hz|%|deg|px|°|MiB|KiB)"
VALUE = r"(?P<value>-?\d+(?:\.\d+)?|true|false|\"[^\"\n]*\"|/[\w/]+)"
# After a unit a colon may follow ("(0.1 s: ...)"); after a bare value it starts what the value means.
END = r"(?:\s*" + UNITS + r"(?=\s*(?:\)|;|:|,|\s+by default|\s+default))|(?=\s*(?:\)|;|,|\s+by default|\s+default)))"


def _module_and_config(kind: str) -> tuple[Any, type]:
    module, _, cls = NODES[kind].partition(":")
    mod = importlib.import_module(module)
    return mod, getattr(mod, cls).Config


def _defaults(config: type) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for f in dataclasses.fields(config):
        if f.default is not dataclasses.MISSING:
            out[f.name] = f.default
        elif f.default_factory is not dataclasses.MISSING:
            out[f.name] = f.default_factory()
    return out


@pytest.fixture(scope="module")
def nodes() -> dict[str, tuple[str, dict[str, Any]]]:
    """node kind -> (its contract docstring, its parameters' defaults)."""
    out = {}
    for kind in NODES:
        mod, config = _module_and_config(kind)
        out[kind] = (mod.__doc__ or "", _defaults(config))
    return out


def _parse(text: str) -> Any:
    text = text.strip()
    if re.fullmatch(r"-?\d+(?:\.\d+)?", text):
        return float(text)
    if text.startswith('"') and text.endswith('"'):
        return text[1:-1]
    if text.startswith("/"):
        return text
    return yaml.safe_load(text)


def _agrees(doc: Any, raw: str, unit: str, code: Any) -> bool:
    """A documented value against the code's default; a number as precisely as it is written."""
    if isinstance(doc, float) and isinstance(code, (int, float)) and not isinstance(code, bool):
        places = len(raw.partition(".")[2])
        if unit.strip() == "%":
            doc, places = doc / 100.0, places + 2
        return round(float(code), places) == round(doc, places)
    if isinstance(code, list | tuple) and isinstance(doc, list | tuple):
        return list(code) == list(doc)
    return doc == code


def _prose_claims(text: str, names: set[str], backticks: bool) -> list[tuple[str, int, str, Any, str]]:
    """(name, offset, raw value, parsed value, unit) for each `name (value)` in `text`."""
    tick = "`" if backticks else "`?"
    pattern = re.compile(tick + r"(?P<name>[a-z][a-z0-9_]*)" + tick + r"\s*\(\s*" + VALUE + END)
    out = []
    for m in pattern.finditer(text):
        if m.group("name") in names:
            unit = text[m.end("value") : m.end()].strip()
            out.append((m.group("name"), m.start(), m.group("value"), _parse(m.group("value")), unit))
    return out


def _line(text: str, offset: int) -> int:
    return text.count("\n", 0, offset) + 1


def test_node_contracts_give_the_code_defaults(nodes: dict[str, tuple[str, dict[str, Any]]]) -> None:
    wrong, seen = [], 0
    for kind, (doc, defaults) in nodes.items():
        for name, _, raw, value, unit in _prose_claims(doc, set(defaults), backticks=False):
            seen += 1
            if not _agrees(value, raw, unit, defaults[name]):
                wrong.append(f"{kind}: {name} documented as {raw} {unit}, code default {defaults[name]!r}")
    assert seen >= 10, "the contracts' defaults are no longer found: update this test's patterns"
    assert not wrong, "\n".join(wrong)


def _owner(name: str, before: str, nodes: dict[str, tuple[str, dict[str, Any]]]) -> list[str]:
    """The nodes a parameter mentioned after `before` (its paragraph so far) can belong to."""
    owners = [k for k, (_, d) in nodes.items() if name in d]
    named = [m.group(1) for m in re.finditer(r"`(\w+)`", before) if m.group(1) in owners]
    return [named[-1]] if named else owners


def _tables(text: str, column: str = "default") -> list[tuple[int, list[list[str]], int]]:
    """(first line, rows of cells, index of `column`) of each markdown table with that column."""
    out, lines, i = [], text.splitlines(), 0
    while i < len(lines):
        if not lines[i].startswith("|"):
            i += 1
            continue
        start = i
        while i < len(lines) and lines[i].startswith("|"):
            i += 1
        rows = [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in lines[start:i]]
        header = [c.lower() for c in rows[0]]
        if column in header and len(rows) > 2:
            out.append((start + 1, rows[2:], header.index(column)))
    return out


def _cell_value(cell: str) -> tuple[str, Any] | None:
    m = re.match(r"`([^`]*)`|(-?\d+(?:\.\d+)?)", cell)
    if m is None:
        return None
    raw = m.group(1) if m.group(1) is not None else m.group(2)
    return raw, (_parse(raw) if m.group(2) is not None else yaml.safe_load(raw) if raw else "")


def test_docs_give_the_code_defaults(nodes: dict[str, tuple[str, dict[str, Any]]]) -> None:
    names = {n for _, d in nodes.values() for n in d}
    wrong, seen = [], 0
    for path in sorted(DOCS.glob("*.md")):
        text = path.read_text()
        for name, offset, raw, value, unit in _prose_claims(text, names, backticks=True):
            para_start = text.rfind("\n\n", 0, offset) + 1
            owners = _owner(name, text[para_start:offset], nodes)
            seen += 1
            codes = {k: nodes[k][1][name] for k in owners}
            if not any(_agrees(value, raw, unit, c) for c in codes.values()):
                wrong.append(f"{path.name}:{_line(text, offset)}: {name} documented as {raw} {unit}, code: {codes}")
            elif len(owners) > 1 and len({repr(c) for c in codes.values()}) > 1:
                wrong.append(f"{path.name}:{_line(text, offset)}: {name} of which node? ({sorted(owners)}: name it)")
        for first, rows, col in _tables(text):
            listed = [m.group(1) for r in rows if (m := re.fullmatch(r"`(\w+)`", r[0])) and m.group(1) in names]
            if not listed:
                continue
            holders = [k for k, (_, d) in nodes.items() if all(n in d for n in listed)]
            for r in rows:
                m = re.fullmatch(r"`(\w+)`", r[0])
                if m is None or m.group(1) not in names or col >= len(r) or r[col] == "(required)":
                    continue
                name, cell = m.group(1), _cell_value(r[col])
                if cell is None:
                    continue
                owners = holders if len(holders) == 1 else [k for k, (_, d) in nodes.items() if name in d]
                codes = {k: nodes[k][1][name] for k in owners}
                seen += 1
                if not any(_agrees(cell[1], cell[0], "", c) for c in codes.values()):
                    wrong.append(f"{path.name}:{first} (table): {name} documented as {r[col]!r}, code: {codes}")
    assert seen >= 40, "the docs' defaults are no longer found: update this test's patterns"
    assert not wrong, "\n".join(wrong)


def _live(kind: str) -> dict[str, bool]:
    _, config = _module_and_config(kind)
    return {f.name: bool(f.metadata.get("live")) for f in dataclasses.fields(config)}


def test_bus_md_says_which_parameters_change_at_runtime() -> None:
    """docs/bus.md's "What can change, per node": every parameter a row names exists, and is live in
    the live column and read-only in the other."""
    text = (DOCS / "bus.md").read_text()
    rows = [r for first, rows, _ in _tables(text, "live") for r in rows]
    wrong, seen = [], 0
    for row in rows:
        kinds = [k for k in re.findall(r"`(\w+)`", row[0]) if k in NODES]
        if not kinds or len(row) < 3:
            continue
        for kind in kinds:
            live = _live(kind)
            for col, want in ((row[1], True), (row[2], False)):
                for name in re.findall(r"`([a-z][a-z0-9_]*)`", col):
                    seen += 1
                    if name not in live:
                        wrong.append(f"{kind}: {name} is not a parameter")
                    elif live[name] != want:
                        wrong.append(f"{kind}: {name} is {'live' if live[name] else 'read-only'}")
    assert seen >= 20, "the table is no longer found: update this test"
    assert not wrong, "\n".join(wrong)


def test_node_defaults_are_their_cores() -> None:
    """A node parameter that its pure core also has defaults to the core's value (one source): the
    commander's, by the same names, are MissionParams' (bus.core_params builds it from the config)."""
    from go2vlm.behavior.mission import MissionParams

    core = MissionParams()
    ours = _defaults(_module_and_config("commander")[1])
    shared = [f.name for f in dataclasses.fields(core) if f.name in ours]
    assert len(shared) >= 8
    assert {n: ours[n] for n in shared} == {n: getattr(core, n) for n in shared}


# node kind -> the pure cores whose declared fields (go2vlm/declare.py `param`) it takes over
NODE_CORES = {
    "commander": (
        "go2vlm.behavior.mission:MissionParams",
        "go2vlm.behavior.planner:PlannerParams",
        "go2vlm.behavior.navigate:NavParams",
        "go2vlm.behavior.strategies.explore:ExploreParams",
    ),
    "safety": ("go2vlm.safety.limits:Limits", "go2vlm.safety.guard:GuardConfig", "go2vlm.safety.health:HealthPolicy"),
    "target_tracker": ("go2vlm.perception.tracking:TrackingParams",),
    "object_memory": (
        "go2vlm.perception.tracking:TrackingParams",
        "go2vlm.world.memory:MemoryParams",
        "go2vlm.statefiles:FileCaps",
    ),
}


def _cls(path: str) -> type:
    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)  # type: ignore[no-any-return]


@pytest.mark.parametrize("kind", sorted(NODE_CORES))
def test_shared_parameters_are_declared_once_on_the_core(kind: str) -> None:
    """Every core field declared as a parameter that the node has is taken over with `from_core`
    (default, help, bounds, live: the core's), and the node never spells a core field's help again."""
    from go2vlm.declare import CORE

    config = _module_and_config(kind)[1]
    cores = [_cls(c) for c in NODE_CORES[kind]]
    declared = {(core, f.name): f for core in cores for f in dataclasses.fields(core) if f.metadata.get("help")}
    helps = {f.metadata["help"] for f in declared.values()}
    linked = 0
    for f in dataclasses.fields(config):
        link = f.metadata.get(CORE)
        if link is None:
            assert f.name not in {name for _, name in declared}, f"{kind}.{f.name}: use from_core"
            assert f.metadata.get("help") not in helps, f"{kind}.{f.name} repeats a core's help: use from_core"
            continue
        linked += 1
        core_field = declared[link]
        own = {k: v for k, v in core_field.metadata.items() if k != CORE}  # a core field may take over another's
        assert {k: v for k, v in f.metadata.items() if k != CORE} == own, f.name
        assert _defaults(config)[f.name] == getattr(link[0](), link[1]), f.name
    assert linked >= 4, kind
