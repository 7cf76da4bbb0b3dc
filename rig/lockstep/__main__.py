"""``python -m rig.lockstep``: builds the fast path's extension module (part of ``make native``)."""

import sys

from plant.native_build import NativeBuildError
from rig.lockstep import build

try:
    print(build())
except NativeBuildError as e:
    sys.exit(str(e))
