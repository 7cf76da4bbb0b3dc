"""What the service keeps besides runs: uploaded firmware, stored once under its SHA-256, and uploaded
scenarios, stored under a name of their own after the validator has read them. Names from a request
reach the file system only through the patterns below; uploads are size-limited and written to a
temporary file first, renamed into place only when whole."""

from __future__ import annotations

import hashlib
import os
import re
import tempfile
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Final

SHA256: Final = re.compile(r"[0-9a-f]{64}")
NAME: Final = re.compile(r"[a-z0-9][a-z0-9_]{0,63}")
MAX_FIRMWARE: Final = 64 << 20
MAX_SCENARIO: Final = 256 << 10


class UploadError(ValueError):
    def __init__(self, message: str, status: int = 422) -> None:
        super().__init__(message)
        self.status = status


class Store:
    def __init__(self, data: Path) -> None:
        self.firmware_dir, self.scenario_dir = data / "firmware", data / "scenarios"
        self.sweep_dir = data / "sweeps"
        self.firmware_dir.mkdir(parents=True, exist_ok=True)
        self.scenario_dir.mkdir(parents=True, exist_ok=True)

    # ---- firmware -----------------------------------------------------------------------------

    async def put_firmware(self, chunks: AsyncIterator[bytes], limit: int = MAX_FIRMWARE) -> tuple[str, int]:
        """Stores an upload (a program the DUT runs) under its SHA-256; (the hash, its size)."""
        digest, size = hashlib.sha256(), 0
        fd, tmp = tempfile.mkstemp(dir=self.firmware_dir, prefix=".upload-")
        try:
            with os.fdopen(fd, "wb") as f:
                async for chunk in chunks:
                    size += len(chunk)
                    if size > limit:
                        raise UploadError(f"firmware over the limit of {limit} bytes", 413)
                    digest.update(chunk)
                    f.write(chunk)
            if size == 0:
                raise UploadError("an empty upload is no firmware")
            sha = digest.hexdigest()
            path = self.firmware_dir / sha
            if path.exists():  # stored once
                return sha, size
            os.chmod(tmp, 0o755)
            os.replace(tmp, path)
            return sha, size
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)

    def firmware(self, sha: str) -> Path | None:
        if not SHA256.fullmatch(sha):
            return None
        path = self.firmware_dir / sha
        return path if path.is_file() else None

    def firmware_list(self) -> list[dict[str, object]]:
        return [{"sha256": p.name, "size": p.stat().st_size} for p in sorted(self.firmware_dir.iterdir())
                if SHA256.fullmatch(p.name)]

    # ---- scenarios ----------------------------------------------------------------------------

    def put_scenario(self, name: str, text: bytes) -> Path:
        """Checks an uploaded scenario with the validator ``rig validate`` uses and stores it as NAME
        (a name of the library cannot be taken); UploadError with the validator's words."""
        from rig.run_cmd import LIBRARY
        from scenarios.schema import ScenarioError, load

        if not NAME.fullmatch(name):
            raise UploadError(f"name {name!r}: lower-case letters, digits and _, at most 64")
        if (LIBRARY / f"{name}.toml").exists():
            raise UploadError(f"{name!r} is a library scenario's name; choose another", 409)
        if len(text) > MAX_SCENARIO:
            raise UploadError(f"a scenario over {MAX_SCENARIO} bytes", 413)
        fd, tmp = tempfile.mkstemp(dir=self.scenario_dir, prefix=".upload-", suffix=".toml")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(text)
            try:
                load(tmp)
            except ScenarioError as e:
                raise UploadError(str(e).replace(tmp, f"{name}.toml")) from e
            path = self.scenario_dir / f"{name}.toml"
            os.replace(tmp, path)
            return path
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)

    def scenario(self, name: str) -> Path | None:
        """A library scenario's file, or an uploaded one's; None for any other name."""
        from rig.run_cmd import LIBRARY

        if not NAME.fullmatch(name):
            return None
        for folder in (LIBRARY, self.scenario_dir):
            path = folder / f"{name}.toml"
            if path.is_file():
                return path
        return None

    def put_sweep(self, text: bytes) -> Path:
        """A sweep spec from a request, stored once under its SHA-256 (it is checked by the caller)."""
        if len(text) > MAX_SCENARIO:
            raise UploadError(f"a sweep spec over {MAX_SCENARIO} bytes", 413)
        self.sweep_dir.mkdir(exist_ok=True)
        path = self.sweep_dir / f"{hashlib.sha256(text).hexdigest()}.toml"
        if not path.exists():
            fd, tmp = tempfile.mkstemp(dir=self.sweep_dir, prefix=".upload-", suffix=".toml")
            with os.fdopen(fd, "wb") as f:
                f.write(text)
            os.replace(tmp, path)
        return path

    def uploaded_scenarios(self) -> list[Path]:
        return sorted(p for p in self.scenario_dir.glob("*.toml") if NAME.fullmatch(p.stem))
