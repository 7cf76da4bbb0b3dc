"""Builds the STM32 tier's engine: QEMU's ``qemu-system-arm`` from Debian's source package with the
rig's STM32F4 device models (qemu/, QEMU's licence) compiled in, and nothing else that QEMU can leave
out (one target, no GUI, no tools, no documentation, no user networking, only the devices qemu/devices.mak
names), and with our patches to QEMU itself (qemu/patches/: each says what it fixes).

QEMU loads no device from outside its own build, so the models must be compiled in; the build takes
minutes, so its binary is cached outside the tree, in ``~/.cache/rig/stm32-engine/<key>/`` (or under
``$XDG_CACHE_HOME``), keyed by the SHA-256 of everything that goes into it: the source package (its
.dsc, which holds the tarballs' hashes), the model sources, the configure flags and this file. A second
``make stm32-engine`` with nothing changed builds nothing and prints where the binary is.

QEMU 7.2, Debian 12's own: every build dependency is in bookworm's main archive (QEMU 10 from
bookworm-backports needs a meson newer than 1.5, which bookworm does not have), and the Cortex-M4,
NVIC, SysTick and the STM32F405 SoC the models extend are all there. The source comes with apt-get
from a private apt state (its own sources list, made from the machine's Debian archives with deb-src,
its own lists and cache), so the machine's apt configuration is never touched. The unpacked source and
the build tree stay in the cache too, so a change of a model recompiles only that model.
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import hashlib
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

from rig.emulators.chips import gen as chip_registers

REPO = Path(__file__).resolve().parents[2]
MODELS = REPO / "qemu"
#: changes to QEMU itself (unified diffs, applied in name order to the unpacked source), kept apart from
#: the models that go into hw/rig: each says what it fixes and why
PATCHES = "patches"
#: the chip core (MIT, ours): compiled into the engine as the slaves on the STM32's I2C, in hw/rig/chips
CHIP_CORE = REPO / "emulators" / "chips"
APT_INSTALL = REPO / "tools" / "apt-install.sh"
SOURCE_PACKAGE = "qemu"
#: the upstream release this engine is written for (the .dsc's version must start with it)
UPSTREAM = "7.2"
BINARY = "qemu-system-arm"
#: the smallest build that runs a Cortex-M machine: every optional feature off (no GUI, audio, user
#: networking, block drivers, ...), no tools, no docs, no firmware blobs, only arm-softmmu and only the
#: devices of qemu/devices.mak. QEMU's arm targets need libfdt (the A-profile boot path links it).
CONFIGURE_FLAGS = (
    "--target-list=arm-softmmu",
    "--without-default-features",
    "--without-default-devices",
    "--enable-fdt=system",
    "--disable-tools",
    "--disable-docs",
    "--disable-install-blobs",
    "--disable-user",
    "--disable-debug-info",
)
#: what the build needs, as Debian packages, and how to tell each is there
BUILD_DEPENDS = {
    "meson": ("command", "meson"),
    "ninja-build": ("command", "ninja"),
    "pkg-config": ("command", "pkg-config"),
    "dpkg-dev": ("command", "dpkg-source"),
    "patch": ("command", "patch"),
    "libglib2.0-dev": ("pkg-config", "glib-2.0"),
    "libpixman-1-dev": ("pkg-config", "pixman-1"),
    "libfdt-dev": ("file", "/usr/include/libfdt.h"),  # (Debian's ships no .pc file)
    "zlib1g-dev": ("pkg-config", "zlib"),
}
#: how many engines (one per set of inputs, e.g. one per branch or worktree) the cache keeps at least,
#: those used last, and for how long it keeps any engine since its last use: by count alone, worktrees
#: building in turn (an edit a build) removed another's engine while its suite was busy elsewhere, and
#: that suite's STM32 tests found no engine
KEEP_ENGINES = 12
KEEP_USED_S = 2 * 24 * 3600
#: the lines that make QEMU's build see hw/rig (appended once to the unpacked source's files)
HOOKS = {Path("hw/meson.build"): "subdir('rig')\n", Path("hw/Kconfig"): "source rig/Kconfig\n"}


class EngineBuildError(RuntimeError):
    """Something the build needs is missing, or a step of it failed."""


def cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "rig" / "stm32-engine"


def model_files(models: Path = MODELS) -> list[Path]:
    return sorted(p for p in models.rglob("*") if p.is_file() and p.relative_to(models).parts[0] != PATCHES)


def patch_files(models: Path = MODELS) -> list[Path]:
    return sorted((models / PATCHES).glob("*.patch"))


def chip_core_sources(chips: Path = CHIP_CORE) -> dict[str, bytes]:
    """The chip core's C files and its generated register header, by their path under hw/rig."""
    files = {f"chips/{p.name}": p.read_bytes() for p in sorted([*chips.glob("*.c"), *chips.glob("*.h")])}
    files["chips/chip_registers.h"] = chip_registers.header().encode()
    return files


def engine_sources(models: Path = MODELS, chips: Path = CHIP_CORE) -> dict[str, bytes]:
    """What goes into hw/rig: the models (qemu/) and the chip core, by their paths there."""
    files = {p.relative_to(models).as_posix(): p.read_bytes() for p in model_files(models)}
    return files | chip_core_sources(chips)


def source_dsc(cache: Path) -> Path | None:
    """The newest QEMU 7.2 source package already downloaded into the cache, if any."""
    found = sorted((cache / "src").glob(f"{SOURCE_PACKAGE}_{UPSTREAM}*.dsc"))
    return found[-1] if found else None


def inputs_hash(dsc: Path, models: Path = MODELS, chips: Path = CHIP_CORE) -> str:
    """SHA-256 of every input of the binary: the source package, the models and the chip core (names and
    contents), the flags, this file. Files' times do not count: a checkout of the same sources finds the
    same engine."""
    h = hashlib.sha256()
    h.update(dsc.name.encode() + b"\0" + dsc.read_bytes())
    for name, data in sorted(engine_sources(models, chips).items()):
        h.update(name.encode() + b"\0" + data)
    h.update(_unpacked_stamp(dsc, models).encode())
    h.update("\0".join(CONFIGURE_FLAGS).encode())
    h.update(Path(__file__).read_bytes())
    return h.hexdigest()


def prune(cache: Path, keep: int = KEEP_ENGINES, keep_used_s: float = KEEP_USED_S) -> None:
    """Removes the engines beyond the ``keep`` used last that have not been used for ``keep_used_s``
    (each is about 9 MB; the work tree stays)."""
    engines = [d for d in cache.iterdir() if d.is_dir() and re.fullmatch(r"[0-9a-f]{16}", d.name)]
    engines.sort(key=lambda d: d.stat().st_mtime, reverse=True)
    unused_since = time.time() - keep_used_s
    for old in engines[keep:]:
        if old.stat().st_mtime < unused_since:
            shutil.rmtree(old, ignore_errors=True)


def sources_missing() -> str | None:
    """Why this rig cannot make its engine, or None: a rig installed from a wheel carries the chip core's
    headers but not QEMU's models (qemu/) nor the chip core's C, so it has no inputs to build or find one."""
    if (MODELS / "devices.mak").is_file() and any(CHIP_CORE.glob("*.c")):
        return None
    return ("the STM32 tier's engine (QEMU with the rig's models) is built from a clone of the rig: this "
            f"rig has no model sources ({MODELS} is not there; an installed rig does not carry them). "
            "Run the STM32 tier from a clone: `make stm32-engine`, then its `.venv/bin/rig run --mcu ...`")


def cached_binary(cache: Path | None = None) -> Path | None:
    """The engine built from the current inputs, or None when it has not been built, or cannot be
    (nothing is downloaded or built here: the tests ask this)."""
    if sources_missing() is not None:
        return None
    cache = cache or cache_dir()
    dsc = source_dsc(cache)
    if dsc is None:
        return None
    binary = cache / inputs_hash(dsc)[:16] / BINARY
    if not binary.is_file():
        return None
    with contextlib.suppress(OSError):  # (used now: the last to be pruned; a read-only cache stays as it is)
        os.utime(binary.parent)
    return binary


def _missing_build_depends() -> list[str]:
    missing = []
    for package, (kind, what) in BUILD_DEPENDS.items():
        if kind == "command":
            present = shutil.which(what) is not None
        elif kind == "file":
            present = Path(what).is_file()
        else:
            present = shutil.which("pkg-config") is not None and subprocess.run(
                ["pkg-config", "--exists", what], check=False).returncode == 0
        if not present:
            missing.append(package)
    return missing


def _codename() -> str:
    for line in Path("/etc/os-release").read_text().splitlines():
        if line.startswith("VERSION_CODENAME="):
            return line.split("=", 1)[1].strip('"')
    raise EngineBuildError("/etc/os-release names no VERSION_CODENAME: not a Debian release")


def deb_src_lines(codename: str, etc: Path = Path("/etc/apt")) -> list[str]:
    """The machine's Debian archives (its binary sources for the release, its updates and its security
    suite) as one-line deb-src entries: the same mirrors, signed by the same keys."""
    entries: list[tuple[str, str, str, str]] = []  # (options, uri, suite, components)
    suites = {codename, f"{codename}-updates", f"{codename}-security"}
    for path in [etc / "sources.list", *sorted((etc / "sources.list.d").glob("*.list"))]:
        if path.is_file():
            for line in path.read_text().splitlines():
                m = re.match(r"\s*deb\s+(\[[^]]*\]\s+)?(\S+)\s+(\S+)\s+(.+)", line.split("#", 1)[0])
                if m:
                    entries.append(((m.group(1) or "").strip(), m.group(2), m.group(3), m.group(4).strip()))
    for path in sorted((etc / "sources.list.d").glob("*.sources")):
        for stanza in re.split(r"\n\s*\n", path.read_text()):
            fields: dict[str, str] = {}
            for line in stanza.splitlines():
                if not line.startswith("#") and ":" in line:
                    key, value = line.split(":", 1)
                    fields[key.strip().lower()] = value.strip()
            if "deb" not in fields.get("types", "").split() or fields.get("enabled", "yes") == "no":
                continue
            options = f"[signed-by={fields['signed-by']}]" if "signed-by" in fields else ""
            for uri in fields.get("uris", "").split():
                for suite in fields.get("suites", "").split():
                    entries.append((options, uri, suite, fields.get("components", "main")))
    lines = [" ".join(filter(None, ("deb-src", o, u, s, c))) for o, u, s, c in entries if s in suites]
    return list(dict.fromkeys(lines))


def download_source(cache: Path) -> Path:
    """apt-get source --download-only into cache/src, from a private apt state in cache/apt."""
    apt = cache / "apt"
    lines = deb_src_lines(_codename())
    if not lines:
        raise EngineBuildError("no Debian archive in /etc/apt to take QEMU's source package from")
    for d in ("etc", "lists/partial", "cache/archives/partial"):
        (apt / d).mkdir(parents=True, exist_ok=True)
    (apt / "etc" / "sources.list").write_text("\n".join(lines) + "\n")
    options = [f"-oDir::Etc::SourceList={apt / 'etc' / 'sources.list'}", "-oDir::Etc::SourceParts=/dev/null",
               f"-oDir::State::Lists={apt / 'lists'}", f"-oDir::Cache={apt / 'cache'}", "-qq"]
    if os.geteuid() == 0:  # (apt's _apt user cannot write into a root-owned cache)
        options.append("-oAPT::Sandbox::User=root")
    (cache / "src").mkdir(parents=True, exist_ok=True)
    print(f"stm32-engine: downloading QEMU's source package ({', '.join(lines)})", flush=True)
    for args in (["update"], ["source", "--download-only", SOURCE_PACKAGE]):
        done = subprocess.run(["apt-get", *options, *args], cwd=cache / "src", check=False)
        if done.returncode:
            raise EngineBuildError(f"apt-get {' '.join(args)} failed (exit {done.returncode})")
    dsc = source_dsc(cache)
    if dsc is None:
        raise EngineBuildError(f"apt-get source brought no {SOURCE_PACKAGE} {UPSTREAM} source package "
                               f"into {cache / 'src'}")
    return dsc


def _write_if_changed(path: Path, data: bytes) -> None:
    """Unchanged files keep their times, so ninja recompiles only what changed."""
    if not path.is_file() or path.read_bytes() != data:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)


def _unpacked_stamp(dsc: Path, models: Path = MODELS) -> str:
    """What an unpacked tree was made from: the source package and our patches (name and SHA-256)."""
    patches = [f"{p.name} {hashlib.sha256(p.read_bytes()).hexdigest()}" for p in patch_files(models)]
    lines = [dsc.name, *patches]
    return "\n".join(lines) + "\n"


def prepare_tree(dsc: Path, work: Path, models: Path = MODELS) -> Path:
    """The unpacked source (Debian's patches applied, then ours) with hw/rig = qemu/ and the chip core, and
    the device config. A tree unpacked from another package or with other patches is unpacked afresh (a
    whole rebuild), since a patch cannot be taken back out of an edited tree reliably."""
    src = work / "src"
    stamp = _unpacked_stamp(dsc, models)
    marker = src / ".rig-unpacked"
    if not marker.is_file() or marker.read_text() != stamp:
        shutil.rmtree(src, ignore_errors=True)
        work.mkdir(parents=True, exist_ok=True)
        tmp = work / "src.tmp"
        shutil.rmtree(tmp, ignore_errors=True)
        subprocess.run(["dpkg-source", "--no-check", "-x", str(dsc), str(tmp)], check=True,
                       stdout=subprocess.DEVNULL)
        for patch in patch_files(models):
            done = subprocess.run(["patch", "-p1", "--forward", "--batch", "--no-backup-if-mismatch", "-i",
                                   str(patch)], cwd=tmp, capture_output=True, text=True, check=False)
            if done.returncode:
                raise EngineBuildError(f"{patch.name} does not apply to {dsc.name}:\n"
                                       f"{done.stdout}{done.stderr}")
        tmp.rename(src)
        marker.write_text(stamp)
    rig = src / "hw" / "rig"
    sources = engine_sources(models)
    wanted = {Path(name) for name in sources}
    for name, data in sources.items():
        _write_if_changed(rig / name, data)
    if rig.is_dir():
        for p in rig.rglob("*"):
            if p.is_file() and p.relative_to(rig) not in wanted:
                p.unlink()
    _write_if_changed(src / "configs" / "devices" / "arm-softmmu" / "default.mak",
                      (models / "devices.mak").read_bytes())
    for rel, line in HOOKS.items():
        text = (src / rel).read_text()
        if line not in text:
            (src / rel).write_text(text + line)
    return src


def configure(src: Path, build: Path) -> None:
    stamp = build / ".rig-configure-flags"
    flags = "\n".join(CONFIGURE_FLAGS)
    if stamp.is_file() and stamp.read_text() == flags:
        return
    shutil.rmtree(build, ignore_errors=True)
    build.mkdir(parents=True)
    log = build / "rig-configure.log"
    with log.open("w") as out:
        done = subprocess.run([str(src / "configure"), *CONFIGURE_FLAGS], cwd=build, stdout=out,
                              stderr=subprocess.STDOUT, check=False)
    if done.returncode:
        raise EngineBuildError(f"QEMU's configure failed (exit {done.returncode}): see {log}")
    stamp.write_text(flags)


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def build(cache: Path | None = None, jobs: int | None = None) -> Path:
    """The engine for the current inputs: from the cache when it is there, else built and cached. One
    build at a time per cache (a lock file): a second caller waits, then finds the first one's binary."""
    why = sources_missing()
    if why is not None:
        raise EngineBuildError(why)
    cache = cache or cache_dir()
    cache.mkdir(parents=True, exist_ok=True)
    with (cache / "lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        return _build_locked(cache, jobs)


def _build_locked(cache: Path, jobs: int | None) -> Path:
    dsc = source_dsc(cache) or download_source(cache)
    key = inputs_hash(dsc)
    out = cache / key[:16]
    binary = out / BINARY
    if binary.is_file():
        os.utime(out)  # (used now: pruning keeps it)
        return binary
    missing = _missing_build_depends()
    if missing:
        subprocess.run([str(APT_INSTALL), "stm32-engine", *missing], check=True)
    version = dsc.stem.removeprefix(f"{SOURCE_PACKAGE}_")
    work = cache / f"work-{version}"
    start, cpu_start = time.monotonic(), _children_cpu_s()
    src = prepare_tree(dsc, work)
    configure(src, work / "build")
    jobs = jobs or os.cpu_count() or 1
    print(f"stm32-engine: building {BINARY} (QEMU {version}) in {work} with {jobs} jobs at nice 19",
          flush=True)
    log = work / "build" / "rig-ninja.log"
    with log.open("w") as f:
        done = subprocess.run(["nice", "-n", "19", "ninja", "-j", str(jobs), BINARY], cwd=work / "build",
                              stdout=f, stderr=subprocess.STDOUT, check=False)
    if done.returncode:
        tail = log.read_text(errors="replace").splitlines()[-30:]
        raise EngineBuildError(f"the build failed (exit {done.returncode}), {log}:\n" + "\n".join(tail))
    seconds, cpu = time.monotonic() - start, _children_cpu_s() - cpu_start
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / f"{BINARY}.tmp"
    shutil.copy2(work / "build" / BINARY, tmp)
    tmp.rename(binary)
    info = {"inputs_sha256": key, "source_package": dsc.name, "configure_flags": list(CONFIGURE_FLAGS),
            "models": sorted(engine_sources()),
            "build_seconds": round(seconds, 1), "build_cpu_seconds": round(cpu, 1), "jobs": jobs}
    (out / "build.json").write_text(json.dumps(info, indent=2) + "\n")
    prune(cache)
    # (the wall time follows the machine's load, at nice 19; the CPU time much less)
    print(f"stm32-engine: built in {seconds:.0f} s ({cpu:.0f} s of CPU)", flush=True)
    return binary


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m rig.mcu.stm32_engine", description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, help="parallel compile jobs (default: every core)")
    ap.add_argument("--where", action="store_true",
                    help="only print the cached engine's path (exit 1 when it is not built)")
    args = ap.parse_args(argv)
    if args.where:
        found = cached_binary()
        if found is None:
            print("stm32-engine: not built for the current inputs (make stm32-engine)", file=sys.stderr)
            return 1
        print(found)
        return 0
    try:
        binary = build(jobs=args.jobs)
    except (EngineBuildError, subprocess.CalledProcessError) as e:
        print(f"stm32-engine: {e}", file=sys.stderr)
        return 1
    print(f"stm32-engine: {binary}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
