"""Builds ``build/plant/quadrotor.fmu`` from the C sources and the variable table.

Why a script and not only make rules: the modelDescription and the C header come from one Python table
(``plant/variables.py``), and the zip must be byte-reproducible (sorted entries, fixed timestamps and
permissions), which ``zip`` cannot promise. Usage: ``python -m rig.plant.build [--out DIR]``.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from rig.plant import variables
from rig.plant.artifacts import BUILD

PLANT_DIR = Path(__file__).resolve().parent
DEFAULT_OUT = BUILD / "plant"
C_SOURCES = ("quadrotor_physics.c", "quadrotor_fmi2.c")
#: -O3 and the two -fno flags change no result (no -ffast-math: the arithmetic's order and rounding are
#: the same, errno is not read): they let the step's functions inline into each other (an exported function
#: may otherwise be replaced at load time) and sqrt be one instruction. 15.4 k -> 13.0 k instructions per
#: FC cycle for the plant (bench/cycle_cost.py --breakdown); the library at seeds 0-4 unchanged.
#: -ffp-contract=off and -fno-tree-slp-vectorize keep it so where the compiler may fuse multiply-adds
#: (a CC with -mfma or -march=native, a GNU dialect, aarch64): the inlined derivatives otherwise became
#: vectorized fmaddsub instructions there, a last-bit change to the attitude.
CFLAGS = ["-std=c11", "-O3", "-fno-semantic-interposition", "-fno-math-errno", "-ffp-contract=off",
          "-fno-tree-slp-vectorize", "-Wall", "-Wextra", "-Werror", "-fPIC", "-fvisibility=default"]
ZIP_DATE = (1980, 1, 1, 0, 0, 0)


def write_generated(gen_dir: Path) -> None:
    """Writes the header and the modelDescription generated from the variable table."""
    gen_dir.mkdir(parents=True, exist_ok=True)
    (gen_dir / "quadrotor_vars.h").write_text(variables.c_header())
    (gen_dir / "modelDescription.xml").write_text(variables.model_description())


def compile_library(gen_dir: Path, output: Path, cc: str | None = None) -> None:
    """Compiles the physics and the FMI wrapper into one shared library.

    Sources are compiled from a copy in a fresh temporary folder named the same way every time, with
    the folder mapped away, so that neither the checkout's path nor the temporary name reaches the
    binary.
    """
    cc = cc or os.environ.get("CC", "gcc")
    with tempfile.TemporaryDirectory(prefix="qrbuild-") as tmp:
        src = Path(tmp)
        for name in C_SOURCES + ("quadrotor_physics.h",):
            shutil.copy(PLANT_DIR / "c" / name, src / name)
        for header in (PLANT_DIR / "fmi2").glob("*.h"):
            shutil.copy(header, src / header.name)
        shutil.copy(gen_dir / "quadrotor_vars.h", src / "quadrotor_vars.h")
        cmd = [cc, *CFLAGS, f"-ffile-prefix-map={src}=.", "-shared", "-o", str(output.resolve()),
               *C_SOURCES, "-lm"]
        output.parent.mkdir(parents=True, exist_ok=True)
        result = subprocess.run(cmd, cwd=src, capture_output=True, text=True)
        if result.returncode != 0:
            raise SystemExit(f"compiling the plant failed:\n{' '.join(cmd)}\n{result.stderr}")


def write_fmu(staging: Path, fmu_path: Path) -> None:
    """Zips a staged FMU folder with sorted entries and fixed metadata."""
    tmp = fmu_path.with_suffix(".fmu.tmp")
    with zipfile.ZipFile(tmp, "w") as zf:
        for path in sorted(p for p in staging.rglob("*") if p.is_file()):
            info = zipfile.ZipInfo(path.relative_to(staging).as_posix(), date_time=ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            info.create_system = 3
            zf.writestr(info, path.read_bytes(), compresslevel=9)
    tmp.replace(fmu_path)


def build(out_dir: Path = DEFAULT_OUT) -> Path:
    """Builds the FMU into ``out_dir`` and returns its path."""
    out_dir = out_dir.resolve()
    gen_dir = out_dir / "gen"
    write_generated(gen_dir)
    staging = out_dir / "staging"
    shutil.rmtree(staging, ignore_errors=True)
    (staging / "binaries" / "linux64").mkdir(parents=True)
    shutil.copy(gen_dir / "modelDescription.xml", staging / "modelDescription.xml")
    compile_library(gen_dir, staging / "binaries" / "linux64" / f"{variables.MODEL_IDENTIFIER}.so")
    (staging / "documentation" / "licenses").mkdir(parents=True)
    licences = staging / "documentation" / "licenses"
    shutil.copy(PLANT_DIR / "fmi2" / "LICENSE.txt", licences / "fmi2-headers.txt")
    fmu_path = out_dir / f"{variables.MODEL_IDENTIFIER}.fmu"
    write_fmu(staging, fmu_path)
    # the unzipped copies of earlier builds (plant/fmu.py keeps one per content) are stale now; a
    # process still running one keeps its mapped library
    shutil.rmtree(out_dir / ".unzipped", ignore_errors=True)
    return fmu_path


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder")
    args = parser.parse_args(argv)
    fmu = build(args.out)
    print(f"{fmu}  sha256 {sha256(fmu)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
