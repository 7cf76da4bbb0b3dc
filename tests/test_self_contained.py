"""A clone is the whole project: no tracked file points outside the repository (the shared design
folder beside the checkout on the developers' machines is not in a clone), and every page of docs/ that
the README names exists."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUTSIDE = re.compile(r"\.\./shared|/work/shared|\bspecs/sensors\.md|(?<![\w/])DESIGN\.md")


def tracked() -> list[Path]:
    names = subprocess.run(["git", "ls-files"], cwd=REPO, capture_output=True, text=True, check=True).stdout
    return [REPO / n for n in names.split()]


def test_no_file_points_outside_the_repository() -> None:
    found = []
    for path in tracked():
        if path.suffix in (".so", ".fmu", ".png", ".pdf") or not path.is_file():
            continue
        for no, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            if OUTSIDE.search(line) and path.name != "test_self_contained.py":
                found.append(f"{path.relative_to(REPO)}:{no}: {line.strip()[:100]}")
    assert not found, "\n".join(found)


def test_the_docs_the_readme_names_exist() -> None:
    readme = (REPO / "README.md").read_text()
    named = set(re.findall(r"\((docs/[\w./-]+\.md)", readme))
    assert {"docs/design.md", "docs/sensors.md"} <= named
    assert all((REPO / n).is_file() for n in named), named
