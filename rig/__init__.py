"""The rig: sessions and their clock, DUT adapters, transports, the scenario runner and the command line.

The compiled hot modules (rig/compiled.py) are put in place by the entry points (the CLI, the tests'
conftest, the benches) calling ``rig.compiled.install()``, never as a side effect of importing a package.
"""

__version__ = "0.1.0"
