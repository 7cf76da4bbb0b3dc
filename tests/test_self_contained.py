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


def test_the_readme_is_a_front_door() -> None:
    """The README says what the rig is, the two commands and one command per target, and links on: it
    stays short, and neither it nor the docs it links speak in issue numbers (a user has no tracker)."""
    readme = (REPO / "README.md").read_text()
    assert len(readme.splitlines()) < 250
    assert "make demo" in readme and "make test" in readme and "--mcu" in readme and "--bridge" in readme
    pages = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
    numbered = [f"{p.relative_to(REPO)}: {m.group(0)}" for p in pages
                for m in re.finditer(r"\bissues? #?\d+", p.read_text(), re.I)]
    assert not numbered, numbered
