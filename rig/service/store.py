"""What the service keeps besides runs: uploaded firmware and scenarios, each stored once under its
SHA-256 (a scenario after the validator has read it). A scenario's name points at a version (the
database's scenario_versions): a run records the versions it was queued with and flies those, so an
upload under the same name later changes no run already queued, and nothing is replaced silently (a
name that points at another version is taken only when the request says replace). Names from a request
reach the file system only through the patterns below; uploads are size-limited and written to a
temporary file first, renamed into place only when whole."""

from __future__ import annotations

import datetime
import hashlib
import json
import math
import os
import re
import tempfile
import tomllib
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any, Final, TypeVar

from rig.service.db import Db
from rig.service.images import HEAD, LINUX, ImageKindError, kind_of

T = TypeVar("T")

SHA256: Final = re.compile(r"[0-9a-f]{64}")
NAME: Final = re.compile(r"[a-z0-9][a-z0-9_]{0,63}")
MAX_FIRMWARE: Final = 64 << 20
MAX_SCENARIO: Final = 256 << 10
#: a sweep's spec as rig sweep reads it, beside its scenario's version (no name starts with a dot)
SWEEP_SPEC: Final = ".spec.toml"


class UploadError(ValueError):
    def __init__(self, message: str, status: int = 422) -> None:
        super().__init__(message)
        self.status = status


class Store:
    def __init__(self, data: Path, db: Db) -> None:
        self.firmware_dir, self.scenario_dir = data / "firmware", data / "scenarios"
        self.sweep_dir, self.board_dir = data / "sweeps", data / "boards"
        self.db = db
        self.firmware_dir.mkdir(parents=True, exist_ok=True)
        self.scenario_dir.mkdir(parents=True, exist_ok=True)
        self._adopt_named_files()

    # ---- firmware -----------------------------------------------------------------------------

    async def put_firmware(self, chunks: AsyncIterator[bytes], limit: int = MAX_FIRMWARE
                           ) -> tuple[str, int, str]:
        """Stores an upload (a Linux program the DUT runs, or an AVR or ARM image a board flies) under its
        SHA-256; (the hash, its size, its kind: rig/service/images.py). Anything else is refused."""
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
            with open(tmp, "rb") as f:
                try:
                    kind = kind_of(f.read(HEAD))
                except ImageKindError as e:
                    raise UploadError(f"the upload is {e}") from None
            sha = digest.hexdigest()
            path = self.firmware_dir / sha
            if path.exists():  # stored once
                return sha, size, kind
            # (only a Linux program may be executed: an MCU image is data for the MCU tier)
            os.chmod(tmp, 0o755 if kind in LINUX else 0o644)
            os.replace(tmp, path)
            return sha, size, kind
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)

    def firmware(self, sha: str) -> Path | None:
        if not SHA256.fullmatch(sha):
            return None
        path = self.firmware_dir / sha
        return path if path.is_file() else None

    def firmware_kind(self, sha: str) -> str | None:
        """An uploaded firmware's kind, from its head (a file uploaded before kinds were told apart is
        told now); None when it is none the service runs, or not there."""
        path = self.firmware(sha)
        if path is None:
            return None
        with open(path, "rb") as f:
            try:
                return kind_of(f.read(HEAD))
            except ImageKindError:
                return None

    def firmware_list(self) -> list[dict[str, object]]:
        return [{"sha256": p.name, "size": p.stat().st_size, "kind": self.firmware_kind(p.name)}
                for p in sorted(self.firmware_dir.iterdir()) if SHA256.fullmatch(p.name)]

    # ---- boards -------------------------------------------------------------------------------

    def put_board(self, text: bytes) -> dict[str, Any]:
        """A board file (TOML) checked as ``rig run --mcu`` checks one, stored once under its SHA-256.
        An EEPROM image named by path is refused: it would be a file of the service's disk."""
        from rig.mcu import board

        if len(text) > MAX_SCENARIO:
            raise UploadError(f"a board file over {MAX_SCENARIO} bytes", 413)
        try:
            eeprom = tomllib.loads(text.decode("utf-8")).get("eeprom")
        except (UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
            raise UploadError(f"the board file is not a readable TOML file: {e}") from None
        if isinstance(eeprom, dict) and "image" in eeprom:
            raise UploadError("board file: eeprom.image names a file on the service's disk: an uploaded "
                              "board may say eeprom.fc = true, or no [eeprom]")
        sha = hashlib.sha256(text).hexdigest()
        self.board_dir.mkdir(exist_ok=True)
        with tempfile.TemporaryDirectory(dir=self.board_dir, prefix=".upload-") as tmp:
            path = Path(tmp) / "board.toml"
            path.write_bytes(text)
            try:
                found = board.load(path)
            except board.BoardError as e:
                raise UploadError(str(e).replace(str(path), "board file")) from None
            os.replace(path, self.board_dir / f"{sha}.toml")
        return {"sha256": sha, "name": found.name, "mcu": found.mcu.name}

    def board(self, name: str) -> Path | str | None:
        """What ``rig run --mcu`` is given for a run's ``board``: a shipped board's name as it is, an
        uploaded board's SHA-256 as its file; None for neither."""
        from rig.mcu import board

        if name in board.names():
            return name
        path = self.board_dir / f"{name}.toml"
        return path if SHA256.fullmatch(name) and path.is_file() else None

    def board_list(self) -> list[dict[str, Any]]:
        """The shipped boards by name, then the uploaded ones by SHA-256, each with its MCU."""
        from rig.mcu import board

        out = []
        shipped = [(n, None, board.BOARDS / f"{n}.toml") for n in board.names()]
        uploaded = [(None, p.stem, p) for p in sorted(self.board_dir.glob("*.toml"))
                    if SHA256.fullmatch(p.stem)]
        for name, sha, path in shipped + uploaded:
            try:
                found = board.load(path)
            except board.BoardError:
                continue
            out.append({"board": name or sha, "name": found.name, "mcu": found.mcu.name,
                        "origin": "shipped" if sha is None else "uploaded"})
        return out

    # ---- scenarios ----------------------------------------------------------------------------

    def put_scenario(self, name: str, text: bytes, replace: bool = False) -> dict[str, Any]:
        """Checks an uploaded scenario with the validator ``rig validate`` uses, stores it once under its
        SHA-256 and points NAME at it (a name of the library cannot be taken; a name that points at
        another version is taken only with ``replace``). UploadError with the validator's words, or
        409. Returns the name, the version, the one it replaced (or None) and whether it is new."""
        from rig.run_cmd import LIBRARY
        from rig.scenarios.schema import ScenarioError, load

        if not NAME.fullmatch(name):
            raise UploadError(f"name {name!r}: lower-case letters, digits and _, at most 64")
        if (LIBRARY / f"{name}.toml").exists():
            raise UploadError(f"{name!r} is a library scenario's name; choose another", 409)
        if len(text) > MAX_SCENARIO:
            raise UploadError(f"a scenario over {MAX_SCENARIO} bytes", 413)
        with tempfile.TemporaryDirectory(dir=self.scenario_dir, prefix=".upload-") as tmp:
            path = Path(tmp) / f"{name}.toml"  # (its stem is the title of a scenario that names none)
            path.write_bytes(text)
            try:
                load(path)
            except ScenarioError as e:
                raise UploadError(str(e).replace(str(path), f"{name}.toml")) from e
        sha = hashlib.sha256(text).hexdigest()
        current = self.db.version(name)
        if current not in (None, sha) and not replace:
            raise UploadError(_taken(name, current, sha), 409)
        self._keep(sha, text)
        previous, pointed = self.db.point(name, sha, replace)
        if not pointed:  # (another upload took the name meanwhile)
            raise UploadError(_taken(name, previous or "?", sha), 409)
        return {"name": name, "sha256": sha, "replaced": previous if previous != sha else None,
                "new": previous != sha}

    def _keep(self, sha: str, text: bytes) -> Path:
        """The version's file, written once (whole, or not at all)."""
        path = self.scenario_dir / f"{sha}.toml"
        if not path.is_file():
            fd, tmp = tempfile.mkstemp(dir=self.scenario_dir, prefix=".upload-", suffix=".toml")
            try:
                with os.fdopen(fd, "wb") as f:
                    f.write(text)
                os.replace(tmp, path)
            finally:
                if os.path.exists(tmp):
                    os.unlink(tmp)
        return path

    def pin(self, name: str) -> str | None:
        """The version NAME stands for now (a library scenario's or an upload's), its file kept in the
        store: a run queued with it flies it even if the name is pointed elsewhere, or the library
        changes, before it runs. None for any other name."""
        from rig.run_cmd import LIBRARY

        if not NAME.fullmatch(name):
            return None
        library = LIBRARY / f"{name}.toml"
        if library.is_file():
            text = library.read_bytes()
            digest = hashlib.sha256(text).hexdigest()
            self._keep(digest, text)
            return digest
        sha = self.db.version(name)
        return sha if sha is not None and self.version_file(sha) is not None else None

    def version_file(self, sha: str) -> Path | None:
        """A stored version's file (its stem is its SHA-256, not its name: see materialize)."""
        if not SHA256.fullmatch(sha):
            return None
        path = self.scenario_dir / f"{sha}.toml"
        return path if path.is_file() else None

    def materialize(self, folder: Path, names: list[str], versions: dict[str, str]) -> dict[str, str]:
        """Each named scenario's pinned version (``versions``; a name not in it is pinned now: a run
        queued before runs recorded versions) as ``folder/NAME.toml``, a link to the version's file: its
        reports are named NAME and its result.json's scenario_file, resolved, is the version's own.
        The versions flown, by name; LookupError for a scenario that is gone."""
        folder.mkdir(parents=True, exist_ok=True)
        flown: dict[str, str] = {}
        for name in names:
            sha = versions.get(name) or self.pin(name)
            target = None if sha is None or not NAME.fullmatch(name) else self.version_file(sha)
            if sha is None or target is None:
                raise LookupError(f"the scenario {name!r} (version {(sha or '?')[:12]}) is no longer there")
            link = folder / f"{name}.toml"
            link.unlink(missing_ok=True)
            link.symlink_to(target.resolve())
            flown[name] = sha
        return flown

    def sweep_spec(self, spec: Path, folder: Path, versions: dict[str, str]) -> tuple[Path, dict[str, str]]:
        """The sweep spec as ``rig sweep`` reads it: its scenario's pinned version beside it in
        ``folder`` (materialize) and the spec, restated there, naming that file instead of the name,
        which rig sweep would look up in the library only. (The restated spec, the version flown.)"""
        try:
            data = tomllib.loads(spec.read_bytes().decode("utf-8"))
            name = data["sweep"]["scenario"]
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise LookupError(f"the sweep spec cannot be read again: {e}") from None
        if not isinstance(name, str):
            raise LookupError("the sweep spec names no scenario")
        flown = self.materialize(folder, [name], versions)
        data["sweep"]["scenario"] = f"{name}.toml"  # (relative to the spec: the link beside it)
        text = f"sweep = {_toml(data['sweep'])}\n"
        if tomllib.loads(text) != data:
            raise LookupError("the sweep spec could not be restated as it was")
        path = folder / SWEEP_SPEC
        path.write_text(text, encoding="utf-8")
        return path, flown

    def uploaded_scenarios(self) -> dict[str, str]:
        """Each uploaded name and the version it points at."""
        return self.db.names()

    def _adopt_named_files(self) -> None:
        """A data folder of a rig from before versions kept each upload as scenarios/NAME.toml: each
        becomes a version its name points at (a name already pointing somewhere keeps that)."""
        for path in sorted(self.scenario_dir.glob("*.toml")):
            text = path.read_bytes()
            sha = hashlib.sha256(text).hexdigest()
            if path.stem == sha or not NAME.fullmatch(path.stem):
                continue
            self._keep(sha, text)
            self.db.point(path.stem, sha, replace=False)
            path.unlink()

    def put_sweep(self, text: bytes, check: Callable[[Path], T]) -> tuple[Path, T]:
        """A sweep spec from a request, stored once under its SHA-256 if ``check`` (given the file)
        returns: a spec it refuses (by raising) leaves nothing behind."""
        if len(text) > MAX_SCENARIO:
            raise UploadError(f"a sweep spec over {MAX_SCENARIO} bytes", 413)
        self.sweep_dir.mkdir(exist_ok=True)
        path = self.sweep_dir / f"{hashlib.sha256(text).hexdigest()}.toml"
        fd, tmp = tempfile.mkstemp(dir=self.sweep_dir, prefix=".upload-", suffix=".toml")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(text)
            checked = check(Path(tmp))
            os.replace(tmp, path)
        finally:
            Path(tmp).unlink(missing_ok=True)
        return path, checked


def _taken(name: str, current: str, sha: str) -> str:
    return (f"{name!r} is already another scenario (version {current[:12]}; this file is {sha[:12]}): "
            f"upload it with ?replace=true to point {name!r} at it (runs queued already fly the version "
            "they were queued with), or choose another name")


def _toml(value: Any) -> str:
    """A value read by tomllib written back as TOML (inline: one line), for a restated spec."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        return repr(value) if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, str):  # JSON's escapes are TOML's; DEL is the one TOML wants escaped besides
        return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(value, list):
        return "[" + ", ".join(map(_toml, value)) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_toml(str(k))} = {_toml(v)}" for k, v in value.items()) + "}"
    if isinstance(value, datetime.date | datetime.time):
        return value.isoformat()
    raise TypeError(f"no TOML for {type(value).__name__}")
