"""The tree shows the program: the stages as folders, no import circle, nothing imported back up.

The import graph is read from the source (every ``import`` and ``from … import``, also those
inside functions), so a lazy import cannot hide a dependency that runs the wrong way.
"""

import ast
from collections.abc import Iterator
from pathlib import Path

APP = Path(__file__).resolve().parent.parent / "app"

# The floors, lowest first: a module may import its own floor and those below, never above.
FLOORS: tuple[tuple[str, ...], ...] = (
    ("app", "app.errors", "app.units", "app.paper", "app.output"),
    ("app.records", "app.dbc"),
    ("app.config",),
    ("app.sources",),
    ("app.decode",),
    ("app.estimate",),
    ("app.detect",),
    ("app.results",),
    ("app.snapshot", "app.pipeline"),
    ("app.sinks",),
    ("app.run_loop",),
    ("app.sim",),
    ("app.gap",),
    ("app.campaign",),
    ("app.cli", "app.__main__"),
)
STAGES = ("sources", "decode", "estimate", "detect", "results", "sinks")


def module_name(path: Path) -> str:
    parts = path.relative_to(APP.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules() -> dict[str, Path]:
    return {module_name(path): path for path in APP.rglob("*.py")}


def imports(path: Path, known: set[str]) -> Iterator[str]:
    """The app modules that ``path`` imports (a ``from pkg import module`` counts as the module)."""
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names if alias.name.split(".")[0] == "app")
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "app":
            for alias in node.names:
                full = f"{node.module}.{alias.name}"
                yield full if full in known else node.module


def graph() -> dict[str, set[str]]:
    found = modules()
    known = set(found)
    return {name: set(imports(path, known)) - {name} for name, path in found.items()}


def floor(module: str) -> int:
    """The floor of a module: that of the longest prefix listed in FLOORS."""
    best, best_len = -1, -1
    for level, prefixes in enumerate(FLOORS):
        for prefix in prefixes:
            if (module == prefix or module.startswith(prefix + ".")) and len(prefix) > best_len:
                best, best_len = level, len(prefix)
    return best


def test_the_stages_are_folders_and_the_top_holds_at_most_a_dozen_modules() -> None:
    top = sorted(path.name for path in APP.glob("*.py"))
    assert len(top) <= 12, top
    for stage in STAGES:
        assert (APP / stage / "__init__.py").is_file(), stage
        assert len(list((APP / stage).glob("*.py"))) >= 3, stage


def test_every_module_has_a_floor() -> None:
    assert [name for name in modules() if floor(name) < 0] == []


def test_nothing_is_imported_back_up() -> None:
    upward = [
        f"{module} (floor {floor(module)}) imports {target} (floor {floor(target)})"
        for module, targets in graph().items()
        for target in targets
        if floor(target) > floor(module)
    ]
    assert upward == []


def test_no_import_circle() -> None:
    edges = graph()
    state: dict[str, int] = {}  # 1: on the path, 2: done
    circles: list[list[str]] = []

    def visit(module: str, path: list[str]) -> None:
        state[module] = 1
        for target in sorted(edges.get(module, ())):
            if state.get(target) == 1:
                circles.append([*path[path.index(target) :], target])
            elif target not in state:
                visit(target, [*path, target])
        state[module] = 2

    for module in sorted(edges):
        if module not in state:
            visit(module, [module])
    assert circles == []


def test_the_checks_see_a_wrong_import() -> None:
    """The checks above would fail on a decoder that imported a sink (the oracle works)."""
    edges = graph()
    assert "app.config" in edges["app.decode.decoder"]
    assert floor("app.sinks.summary") > floor("app.decode.decoder")
    assert floor("app.decode.decoder") > floor("app.config")
