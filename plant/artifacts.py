"""Where the rig's built artifacts are: the one answer every module asks (the FMU, the shim and keeper,
the C extensions, the mypyc build, the reference FC, the virtual bridge, the MCU engine's glue).

* In a source tree (a clone, and its editable install, ``pip install -e .``): the tree's ``build/``,
  which ``make`` and the builds on first use write, rebuilt when a source is newer.
* Installed from a wheel (``pip install .``): ``rig/_build/`` inside the installed package, the same
  layout, filled when the wheel was built (setup.py). Nothing there is rebuilt: the sources beside it
  are the ones it was built from, their times are the unpacking's, and site-packages may be read-only.

The few files of the tree that a run reads and that live outside the Python packages (the reference
FC's key table, ``dut/src/config_keys.h``) travel with the wheel the same way: ``tree_file``.

It lives with the plant, the bottom layer, and imports only the standard library: every layer, the
Makefile's helpers (rig/compiled.py) and the wheel's build (setup.py) read it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Final

#: the ``rig`` package's folder: the tree's ``rig/`` (this file is reached through its link rig/plant),
#: or site-packages' ``rig/``
PACKAGE: Final = Path(__file__).absolute().parent.parent
#: the artifacts' folder inside an installed package; a source tree has none
INSTALLED_BUILD: Final = PACKAGE / "_build"
#: an installed package (from a wheel), as opposed to a source tree
INSTALLED: Final = INSTALLED_BUILD.is_dir()
#: the source tree's root (meaningful only when not INSTALLED)
TREE: Final = PACKAGE.parent
#: where the built artifacts are
BUILD: Final = INSTALLED_BUILD if INSTALLED else TREE / "build"
#: inside BUILD, where an installed package keeps its copies of the tree's files (tree_file)
TREE_COPIES: Final = "tree"
#: the tree's files a run reads from outside the Python packages, relative to the tree's root
TREE_FILES: Final = ("dut/src/config_keys.h",)


def tree_file(relative: str) -> Path:
    """The tree's file ``relative`` (one of TREE_FILES): in a tree, itself; installed, the wheel's copy."""
    assert relative in TREE_FILES, f"{relative} is not shipped with the wheel: add it to TREE_FILES"
    return BUILD / TREE_COPIES / relative if INSTALLED else TREE / relative
