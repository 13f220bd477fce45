"""Count the explicit `Any`s in src/go2vlm and testing_support (what mypy checks), by the place they
stand (docs/typing.md explains each kind).

    python scripts/count_any.py              # the total and the table by kind
    python scripts/count_any.py --files      # ... and the files with the most

An explicit `Any` is every use of the name `Any` (or `typing.Any`) outside an import statement.
tests/test_typing.py fails when the total grows past the figure recorded in docs/typing.md.
"""

from __future__ import annotations

import argparse
import ast
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "go2vlm"
CHECKED = (SRC, ROOT / "testing_support")


# The bus's generic endpoints (and the cyclonedds ones under them): [Any] where any message type goes.
_ENDPOINTS = {"Publisher", "Subscription", "Service", "ServiceClient", "SrvType", "Topic", "DataWriter", "DataReader"}


def _is_any(node: ast.AST) -> bool:
    if isinstance(node, ast.Name):
        return node.id == "Any"
    return isinstance(node, ast.Attribute) and node.attr == "Any" and ast.unparse(node.value) == "typing"


def _kind(node: ast.AST, parents: dict[ast.AST, ast.AST]) -> str:
    """Where this `Any` stands: a parameter, a return, a variable, `**kwargs`, or inside `X[...]`."""
    parent = parents.get(node)
    if isinstance(parent, ast.arg):
        args = parents.get(parent)
        if isinstance(args, ast.arguments) and args.kwarg is parent:
            return "**kwargs: Any"
        if isinstance(args, ast.arguments) and args.vararg is parent:
            return "*args: Any"
        return "parameter: Any"
    if isinstance(parent, (ast.FunctionDef, ast.AsyncFunctionDef)) and parent.returns is node:
        return "-> Any"
    if isinstance(parent, ast.AnnAssign):
        return "variable: Any"
    while isinstance(parent, (ast.Tuple, ast.List)):  # dict[str, Any], Callable[[Any], None]
        parent = parents.get(parent)
    if isinstance(parent, ast.Subscript):
        base = ast.unparse(parent.value).rsplit(".", 1)[-1]
        if base in ("dict", "Mapping"):
            return "dict[str, Any]"
        if base in ("list", "tuple", "Sequence", "Iterable"):
            return "list/tuple/Sequence[Any]"
        if base in _ENDPOINTS:
            return "Publisher/Subscription/Service...[Any]"
        return "Callable/type/Field/dtype[Any]"
    return "other"


def count(roots: tuple[Path, ...] = CHECKED) -> tuple[Counter[str], Counter[str]]:
    """(count by kind, count by file) of the explicit `Any`s under `roots`."""
    kinds: Counter[str] = Counter()
    files: Counter[str] = Counter()
    for path in sorted(p for root in roots for p in root.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        parents = {child: node for node in ast.walk(tree) for child in ast.iter_child_nodes(node)}
        for node in ast.walk(tree):
            if _is_any(node):
                kinds[_kind(node, parents)] += 1
                files[path.relative_to(ROOT).as_posix()] += 1
    return kinds, files


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--files", action="store_true", help="also list the 15 files with the most")
    args = ap.parse_args()
    kinds, files = count()
    print(f"explicit Any in src/go2vlm and testing_support: {sum(kinds.values())}")
    for kind, n in kinds.most_common():
        print(f"{n:6d}  {kind}")
    if args.files:
        print()
        for name, n in files.most_common(15):
            print(f"{n:6d}  {name}")


if __name__ == "__main__":
    main()
