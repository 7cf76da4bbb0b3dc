"""Reading the rig's TOML files (scenarios, sweeps, airframes, FC profiles, board files): one place that
turns a missing file, bytes that are not UTF-8 and TOML that does not parse into one sentence each, so
every file kind reports them alike, and that hashes the bytes it parsed (the run's metadata names the
file by that hash, whatever changes on disk afterwards)."""

from __future__ import annotations

import hashlib
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any


class TomlFileError(ValueError):
    """The file could not be read or is not TOML; the caller puts its own file kind and name around
    the sentence."""


@dataclass(frozen=True)
class TomlFile:
    data: dict[str, Any]
    raw: bytes  # the bytes parsed

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.raw).hexdigest()


def read_toml(path: Path) -> TomlFile:
    """The file's tables and the bytes they came from."""
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise TomlFileError(f"cannot read: {e.strerror}") from None
    try:
        return TomlFile(tomllib.loads(raw.decode("utf-8")), raw)
    except UnicodeDecodeError as e:
        raise TomlFileError(f"not valid TOML: not UTF-8 text ({e.reason} at offset {e.start})") from None
    except tomllib.TOMLDecodeError as e:
        raise TomlFileError(f"not valid TOML: {e}") from None
