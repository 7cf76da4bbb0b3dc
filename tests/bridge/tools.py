"""Builds the bridge's C test tools (bridge/tests/*.c) against the generated headers (the message table's
and the chip core's register tables), when a source is newer than the tool: the link's (link_tool) and
the core's (bridge_tool)."""

from __future__ import annotations

from pathlib import Path

from emulators.chips import gen as chip_gen
from plant.native_build import BUILD, compile_c, is_stale
from rig.bridge import gen

REPO = Path(__file__).resolve().parents[2]
CORE = REPO / "bridge" / "core"
#: the chip core the bridge links: the one the lockstep session runs (emulators/chips)
CHIPS = REPO / "emulators" / "chips"
CHIP_SOURCES = sorted(CHIPS.glob("*.c"))
TABLE = [REPO / "rig" / "bridge" / "messages.py", REPO / "rig" / "bridge" / "gen.py"]
#: as the Makefile's BRIDGE_CFLAGS: strict C99, no fused multiply-adds
FLAGS = ["-std=c99", "-pedantic", "-ffp-contract=off"]


def headers() -> list[Path]:
    """The generated headers, written when their tables changed, and what they are made of."""
    return [gen.write(), chip_gen.write(), *TABLE, *chip_gen.SOURCES, *CORE.glob("*.h"), *CHIPS.glob("*.h")]


def build_tool(name: str, sources: list[Path]) -> Path:
    deps = headers()
    out = BUILD / "bridge" / name
    if is_stale(out, [*sources, *deps]):
        compile_c(sources, out, f"the bridge's {name}", libs=["-lm"],
                  flags=[*FLAGS, f"-I{deps[0].parent}", f"-I{CHIPS}", f"-I{CORE}"])
    return out


def link_tool() -> Path:
    return build_tool("link_tool", [REPO / "bridge" / "tests" / "link_tool.c", CORE / "link.c"])


def bridge_tool() -> Path:
    return build_tool("bridge_tool", [REPO / "bridge" / "tests" / "bridge_tool.c", *sorted(CORE.glob("*.c")),
                                      *CHIP_SOURCES])


def vbridge() -> Path:
    """build/vbridge, as `make vbridge` builds it (rebuilt here when a source is newer)."""
    out = BUILD / "vbridge"
    sources = [REPO / "bridge" / "posix" / "vbridge.c", *sorted(CORE.glob("*.c")), *CHIP_SOURCES]
    deps = headers()
    if is_stale(out, [*sources, *deps, REPO / "rig" / "shim" / "protocol.h"]):
        includes = [deps[0].parent, CHIPS, CORE, REPO / "rig" / "shim"]
        compile_c(sources, out, "the virtual bridge", libs=["-lm"],
                  flags=[*FLAGS, *(f"-I{i}" for i in includes)])
    return out
