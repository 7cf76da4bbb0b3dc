"""Builds the compiled hot modules (rig/compiled.py says what, why, and how they are used):
``python -m rig.mypyc_build``, which ``make compiled`` runs."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from rig.compiled import _SUFFIX, GROUP, MANIFEST, MODULES, OUT, REPO, sha256, source_of


def build() -> None:
    """Compiles MODULES into build/mypyc and writes the manifest (the hashes of the sources used)."""
    from mypyc.build import mypycify
    from setuptools import Distribution

    hashes = {m: sha256(source_of(m)) for m in MODULES}
    shutil.rmtree(OUT, ignore_errors=True)
    OUT.mkdir(parents=True)
    with tempfile.TemporaryDirectory(prefix="rig-mypyc-") as tmp:
        cwd = os.getcwd()
        os.chdir(REPO)  # mypyc names modules by their paths relative to here
        try:
            args = mypyc_options(Path(tmp))
            exts = mypycify([*args, *(str(source_of(m).relative_to(REPO)) for m in MODULES)],
                            group_name=GROUP, target_dir=str(Path(tmp) / "c"), multi_file=True)
            dist = Distribution({"name": "rig-hot", "ext_modules": exts})
            dist.verbose = False  # (no compiler command lines; errors still show)
            cmd = dist.get_command_obj("build_ext")
            cmd.build_lib, cmd.build_temp = str(OUT), str(Path(tmp) / "obj")
            build_extension = cmd.build_extension

            def parallel_build(ext: Any) -> None:  # (the compiler is made when build_ext runs)
                _parallel(cmd.compiler)
                build_extension(ext)

            cmd.build_extension = parallel_build  # type: ignore[method-assign]
            dist.run_command("build_ext")
        finally:
            os.chdir(cwd)
    files = {m: str(Path(*m.split(".")).with_suffix(_SUFFIX).as_posix()) for m in MODULES}
    for f in files.values():
        if not (OUT / f).is_file():
            raise SystemExit(f"rig.compiled: mypyc produced no {f}")
    MANIFEST.write_text(json.dumps({"runtime": f"{GROUP}__mypyc",
                                    "modules": {m: {"file": files[m], "sha256": hashes[m]} for m in MODULES}},
                                   indent=1) + "\n")
    print(f"rig.compiled: {', '.join(MODULES)} compiled into {OUT.relative_to(REPO)}")


def mypyc_options(tmp: Path) -> list[str]:
    """mypy's options for mypyc's analysis. Its cache goes to the build's temporary folder: mypy keeps its
    cache in SQLite, and `make test` runs the linters' mypy beside this build; sharing `.mypy_cache`,
    the second to open the database failed with "database is locked" under load. Modules it imports
    are read for their types, but their own type errors are not ours here."""
    return ["--ignore-missing-imports", "--follow-imports=silent", "--cache-dir", str(tmp / "mypy-cache")]


def _parallel(compiler: Any) -> None:
    """The compiler's compile() with its sources compiled a core each: distutils compiles one after
    another, and the compiled modules' one C file took 45 s of gcc alone (multi_file: a file per module)."""
    if getattr(compiler, "_rig_parallel", False):
        return

    def compile(sources: list[str], output_dir: str | None = None, macros: Any = None,
                include_dirs: Any = None, debug: bool = False, extra_preargs: Any = None,
                extra_postargs: Any = None, depends: Any = None) -> list[str]:
        macros, objects, extra, pp_opts, build = compiler._setup_compile(
            output_dir, macros, include_dirs, sources, depends, extra_postargs)
        cc_args = compiler._get_cc_args(pp_opts, debug, extra_preargs)

        def one(obj: str) -> None:
            src, ext = build[obj]
            compiler._compile(obj, src, ext, cc_args, extra, pp_opts)

        with ThreadPoolExecutor(max(1, len(os.sched_getaffinity(0)))) as pool:
            list(pool.map(one, objects))
        result: list[str] = objects
        return result

    compiler.compile = compile
    compiler._rig_parallel = True


if __name__ == "__main__":
    build()
