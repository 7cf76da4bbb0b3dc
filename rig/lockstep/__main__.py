"""``python -m rig.lockstep``: builds the fast path's extension module (part of ``make native``)."""

import sys

from rig.lockstep import build
from rig.plant.native_build import NativeBuildError

try:
    print(build())
except NativeBuildError as e:
    sys.exit(str(e))
