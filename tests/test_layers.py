"""One import direction (docs/design.md §2): plant <- emulators <- scenarios <- reports <- rig. A lower
layer never imports a higher one, not even inside a function: every import of every module of the five
packages is read from its source and checked. The four lower layers are imported as rig.plant,
rig.emulators, rig.scenarios and rig.reports (docs/layout.md): a module's layer is its name's second part
there, else its first."""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LAYERS = ("plant", "emulators", "scenarios", "reports", "rig")  # bottom to top


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, imported module) for every import statement in the file, at any depth; `from rig import
    scenarios` imports rig.scenarios."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out += [(node.lineno, f"rig.{a.name}") for a in node.names if node.module == "rig"
                    and a.name in LAYERS] or [(node.lineno, node.module)]
    return out


def layer_of(module: str) -> str | None:
    parts = module.split(".")
    if parts[0] == "rig" and len(parts) > 1 and parts[1] in LAYERS[:-1]:
        return parts[1]
    return parts[0] if parts[0] in LAYERS else None


def test_no_layer_imports_a_higher_one() -> None:
    upward = []
    for layer in LAYERS:
        for path in sorted((REPO / layer).rglob("*.py")):
            for line, module in imports(path):
                top = layer_of(module)
                if top is not None and LAYERS.index(top) > LAYERS.index(layer):
                    upward.append(f"{path.relative_to(REPO)}:{line} imports {module}")
    assert not upward, "\n".join(upward)


def test_the_check_sees_an_upward_arrow(tmp_path: Path) -> None:
    bad = tmp_path / "m.py"
    bad.write_text("def f():\n    from rig.session import Session\n    return Session\n")
    assert imports(bad) == [(2, "rig.session")]
    assert layer_of("rig.session") == "rig" and layer_of("rig.plant.fmu") == "plant"
    bad.write_text("from rig import scenarios\nimport rig.reports.junit\n")
    assert [layer_of(m) for _, m in imports(bad)] == ["scenarios", "reports"]
