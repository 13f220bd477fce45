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
    """A node parameter that its pure core also has defaults to the core's value (one source): same
    names through bus.core_params, and the gate's, whose names differ, by this table."""
    from go2vlm.behavior.mission import MissionParams
    from go2vlm.perception.tracking import TrackingParams
    from go2vlm.safety.guard import GuardConfig
    from go2vlm.safety.health import HealthPolicy
    from go2vlm.safety.limits import Limits

    pairs = {"commander": MissionParams(), "target_tracker": TrackingParams()}
    for kind, core in pairs.items():
        _, config = _module_and_config(kind)
        ours = _defaults(config)
        shared = [f.name for f in dataclasses.fields(core) if f.name in ours]
        assert len(shared) >= 8, kind
        assert {n: ours[n] for n in shared} == {n: getattr(core, n) for n in shared}, kind
    gate = _defaults(_module_and_config("safety")[1])
    lim, guard, health = Limits(), GuardConfig(), HealthPolicy()
    assert (gate["max_vx_forward"], gate["max_vx_backward"], gate["max_vy"], gate["max_vyaw"]) == (
        lim.vx_forward, lim.vx_backward, lim.vy, lim.wz
    )  # fmt: skip
    assert (gate["accel_linear"], gate["accel_angular"]) == (lim.accel_linear, lim.accel_angular)
    assert (gate["margin"], gate["blind_speed"], gate["scan_timeout_s"], gate["reaction_s"]) == (
        guard.margin, guard.blind_speed, guard.scan_timeout_s, guard.reaction_s
    )  # fmt: skip
    assert (gate["health_stale_s"], gate["health_clear_s"], gate["health_cap_scale"]) == (
        health.stale_s, health.clear_s, health.cap_scale
    )  # fmt: skip
    assert gate["health_require_state"] == health.require_state
