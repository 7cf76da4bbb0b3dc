"""Builds the bridge's C test tools (bridge/tests/*.c) against the generated message header, when a
source is newer than the tool: the link's (link_tool) and the core's (bridge_tool), for the host and,
cross-built for the STM32G431's Cortex-M4, for QEMU's mps2-an386 (`Tool` runs a script on both and
insists on the same bytes out)."""

from __future__ import annotations

import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from rig.bridge import gen
from rig.bridge.firmware import CC as ARM_CC
from rig.bridge.firmware import M4_FLAGS
from rig.emulators.chips import gen as chips_gen
from rig.plant.artifacts import BUILD
from rig.plant.native_build import compile_c, is_stale

REPO = Path(__file__).resolve().parents[2]
CORE = REPO / "bridge" / "core"
#: the chip core the bridge links: the one the lockstep session runs, and the firmware (emulators/chips)
CHIPS = REPO / "emulators" / "chips"
CHIP_CORE = CHIPS
TABLE = [REPO / "rig" / "bridge" / "messages.py", REPO / "rig" / "bridge" / "gen.py"]
#: as the Makefile's BRIDGE_CFLAGS: strict C99, no fused multiply-adds (the M4 has them in single
#: precision: the same bytes on both need the same arithmetic)
FLAGS = ["-std=c99", "-pedantic", "-ffp-contract=off"]
QEMU_DIR = REPO / "bridge" / "qemu"
QEMU = "qemu-system-arm"
#: a run under QEMU that takes longer than this is killed (the tests' own take well under a second)
QEMU_TIMEOUT_S = 60.0


def _headers(chips: Path) -> list[Path]:
    """The generated headers (rewritten when their tables changed) and the include folders."""
    header = gen.write()
    chips_gen.write()
    return [header.parent, chips, CORE]


def build_tool(name: str, sources: list[Path], chips: Path = CHIPS, m4: bool = False) -> Path:
    """build/bridge/NAME for the host, or NAME-m4.elf for the Cortex-M4 under QEMU (semihosting)."""
    includes = _headers(chips)
    out = BUILD / "bridge" / (f"{name}-m4.elf" if m4 else name)
    if m4:
        sources = [QEMU_DIR / "startup.c", *sources]
    deps = [*sources, *CORE.glob("*.h"), *chips.glob("*.h"), *TABLE, *chips_gen.SOURCES,
            *includes[0].glob("*.h")]
    if m4:
        deps.append(QEMU_DIR / "mps2_an386.ld")
    if is_stale(out, deps):
        flags = [*FLAGS, *(f"-I{i}" for i in includes)]
        if m4:
            flags += [*M4_FLAGS, "--specs=rdimon.specs", f"-T{QEMU_DIR / 'mps2_an386.ld'}"]
        compile_c(sources, out, f"the bridge's {name}" + (" for the Cortex-M4" if m4 else ""), libs=["-lm"],
                  cc=ARM_CC if m4 else None, flags=flags)
    return out


def run_m4(elf: Path, args: list[str], timeout: float = QEMU_TIMEOUT_S,
           qemu_args: tuple[str, ...] = ()) -> subprocess.CompletedProcess[str]:
    """Runs ``elf`` on QEMU's mps2-an386 (a Cortex-M4F) with semihosting: ``args`` are its argv[1:], its
    files are the host's, its exit status is QEMU's. No display, monitor or serial port; a run past
    ``timeout`` is killed (subprocess.run kills and reaps it), so no QEMU outlives the call.
    ``qemu_args`` go to QEMU (bench/bridge_m4_cost.py: -icount)."""
    def esc(arg: str) -> str:
        return arg.replace(",", ",,")  # QEMU's option syntax
    semi = ",".join(["enable=on", "target=native", f"arg={esc(elf.name)}", *(f"arg={esc(a)}" for a in args)])
    cmd = [QEMU, "-M", "mps2-an386", "-nographic", "-monitor", "none", "-serial", "none",
           "-semihosting-config", semi, *qemu_args, "-kernel", str(elf)]
    return subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=timeout)


@dataclass(frozen=True)
class Tool:
    """bridge_tool on the host (``host``), and, when ``m4`` is given, the Cortex-M4 build ``m4`` under
    QEMU with ``m4_twin``, the host build of the same sources: a script's output must be the same byte
    for byte on those two. The output returned is the M4's when ``m4_twin`` is ``host`` (the tests'
    assertions then read what the M4 computed)."""

    host: Path
    m4: Path | None = None
    m4_twin: Path | None = None

    def run(self, script: str, args: tuple[str, ...] = ()) -> str:
        """The tool's output for this script on its standard input."""
        return self.run_bytes(script.encode(), args).decode()

    def run_bytes(self, stdin: bytes, args: tuple[str, ...] = ()) -> bytes:
        """The same for any bytes in; ``args`` go first on the command line (on the M4, before the
        input and output files)."""
        out = _run_host(self.host, stdin, args)
        if self.m4 is None or self.m4_twin is None:
            return out
        twin = out if self.m4_twin == self.host else _run_host(self.m4_twin, stdin, args)
        with tempfile.TemporaryDirectory(prefix="bridge-m4-") as tmp:
            src, dst = Path(tmp) / "in", Path(tmp) / "out"
            src.write_bytes(stdin)
            done = run_m4(self.m4, [*args, str(src), str(dst)])
            assert done.returncode == 0, f"{self.m4.name} under QEMU: status {done.returncode}\n{done.stderr}"
            got = dst.read_bytes()
        if got != twin:
            a, b = twin.splitlines(), got.splitlines()
            i = next((k for k, (x, y) in enumerate(zip(a, b, strict=False)) if x != y), min(len(a), len(b)))
            raise AssertionError(f"the Cortex-M4 and the host differ at line {i + 1} of {len(a)}:\n"
                                 f"  host: {a[i:i + 1]}\n  m4:   {b[i:i + 1]}")
        return got if self.m4_twin == self.host else out


def _run_host(tool: Path, stdin: bytes, args: tuple[str, ...]) -> bytes:
    done = subprocess.run([str(tool), *args], input=stdin, capture_output=True, timeout=120)
    assert done.returncode == 0, done.stderr.decode(errors="replace")
    return done.stdout


def link_tool(m4: bool = False) -> Path:
    return build_tool("link_tool", [REPO / "bridge" / "tests" / "link_tool.c", CORE / "link.c"], m4=m4)


def link_tools(kind: str) -> Tool:
    """link_tool on the host ("host"), or on the host and the Cortex-M4 ("cortex-m4"), byte for byte."""
    return Tool(link_tool()) if kind == "host" else Tool(link_tool(), link_tool(m4=True), link_tool())


def bridge_tool(chips: Path = CHIPS, m4: bool = False) -> Path:
    return build_tool("bridge_tool" if chips == CHIPS else "bridge_tool-chips",
                      [REPO / "bridge" / "tests" / "bridge_tool.c", *sorted(CORE.glob("*.c")),
                       *sorted(chips.glob("*.c"))], chips, m4)


def bridge_tools(kind: str) -> Tool:
    """"host": bridge_tool as the host tests have always run it; "cortex-m4": the core with the real chip
    core (emulators/chips, as the firmware links it) on QEMU's Cortex-M4 as well, byte for byte against
    its host build."""
    if kind == "host":
        return Tool(bridge_tool())
    return Tool(bridge_tool(), bridge_tool(CHIP_CORE, m4=True), bridge_tool(CHIP_CORE))


def vbridge() -> Path:
    """build/vbridge, as `make vbridge` builds it (rebuilt here when a source is newer)."""
    out = BUILD / "vbridge"
    posix = REPO / "bridge" / "posix"
    sources = [*sorted(posix.glob("*.c")), *sorted(CORE.glob("*.c")), *sorted(CHIPS.glob("*.c"))]
    includes = [*_headers(CHIPS), REPO / "rig" / "shim"]
    headers = [*posix.glob("*.h"), *CORE.glob("*.h"), *CHIPS.glob("*.h"), REPO / "rig/shim/protocol.h"]
    if is_stale(out, [*sources, *headers, *TABLE, *chips_gen.SOURCES, *includes[0].glob("*.h")]):
        compile_c(sources, out, "the virtual bridge", libs=["-lm"],
                  flags=[*FLAGS, *(f"-I{i}" for i in includes)])
    return out
