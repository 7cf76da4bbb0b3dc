"""Builds the bridge's C test tools (bridge/tests/*.c) against the generated message header, when a
source is newer than the tool: the link's (link_tool) and the core's (bridge_tool)."""

from __future__ import annotations

from pathlib import Path

from plant.native_build import BUILD, compile_c, is_stale
from rig.bridge import gen

REPO = Path(__file__).resolve().parents[2]
CORE = REPO / "bridge" / "core"
#: the chip core the bridge links: a stand-in until branch chip-core is merged (bridge/standin/)
CHIPS = REPO / "bridge" / "standin"
TABLE = [REPO / "rig" / "bridge" / "messages.py", REPO / "rig" / "bridge" / "gen.py"]


def build_tool(name: str, sources: list[Path]) -> Path:
    header = gen.write()
    out = BUILD / "bridge" / name
    deps = [*sources, *CORE.glob("*.h"), *CHIPS.glob("*.h"), *TABLE, header]
    if is_stale(out, deps):
        compile_c(sources, out, f"the bridge's {name}", libs=["-lm"],
                  flags=["-std=c99", "-pedantic", f"-I{header.parent}", f"-I{CHIPS}", f"-I{CORE}"])
    return out


def link_tool() -> Path:
    return build_tool("link_tool", [REPO / "bridge" / "tests" / "link_tool.c", CORE / "link.c"])


def bridge_tool() -> Path:
    return build_tool("bridge_tool", [REPO / "bridge" / "tests" / "bridge_tool.c", *sorted(CORE.glob("*.c")),
                                      *sorted(CHIPS.glob("*.c"))])


def vbridge() -> Path:
    """build/vbridge, as `make vbridge` builds it (rebuilt here when a source is newer)."""
    out = BUILD / "vbridge"
    sources = [REPO / "bridge" / "posix" / "vbridge.c", *sorted(CORE.glob("*.c")), *sorted(CHIPS.glob("*.c"))]
    header = gen.write()
    if is_stale(out, [*sources, *CORE.glob("*.h"), *CHIPS.glob("*.h"), REPO / "rig" / "shim" / "protocol.h",
                      *TABLE, header]):
        includes = [header.parent, CHIPS, CORE, REPO / "rig" / "shim"]
        compile_c(sources, out, "the virtual bridge", libs=["-lm"],
                  flags=["-std=c99", *(f"-I{i}" for i in includes)])
    return out
