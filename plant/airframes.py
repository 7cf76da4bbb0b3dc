"""Airframes as data: the vehicle's mass, inertia, arm, rotor coefficients, motor lag and ESC range,
one TOML file per airframe, each citing where its numbers come from.

The shipped files are in ``plant/airframes/`` (package data): ``seed-001`` (seed 001's Table 1, the
default for the seed scenarios, physically inconsistent and said so), ``f450`` (450 class) and
``racer-250`` (250 class), both from published identification. A file is::

    [airframe]
    name = "f450"
    class = "450"
    source = "who measured it, where it is published"       # required: an airframe cites its source
    notes = "how the source's figures became these"          # optional
    inconsistent = "why no rigid body has this inertia"      # only the seed's

    [params]                                                 # plant parameters (plant/variables.py)
    mass = 1.4
    ...

The plant's own rules apply to the parameters (``check_parameters``: mass and inertia positive,
the principal moments obeying the triangle inequality, ...): a file that breaks them is refused.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.plant.toml_file import TomlFileError, read_toml
from rig.plant.variables import PARAMETERS, check_parameters, triangle_broken

#: Where the shipped airframe files are
AIRFRAMES_DIR = Path(__file__).resolve().parent / "airframes"
#: The airframe flown when none is named: seed 001's, which the seed scenarios were written for
DEFAULT_AIRFRAME = "seed-001"
#: The plant parameters an airframe may set: what the vehicle is, not where it starts or what it
#: stands on (those are the scenario's)
AIRFRAME_PARAMETERS = ("mass", "arm_length", "k_thrust", "k_torque", "Ixx", "Iyy", "Izz", "motor_tau",
                       "omega_max", "esc_min_us", "esc_max_us", "esc_start_us", "drag_n", "drag_e",
                       "drag_d")
_AIRFRAME_KEYS = ("name", "class", "source", "notes", "inconsistent")
_REQUIRED = ("name", "source")


class AirframeError(ValueError):
    """A bad airframe name or file: ``file: key: what is wrong`` (the CLI prints it, exit 2)."""

    def __init__(self, file: str, key: str, message: str) -> None:
        super().__init__(f"{file}: {key}: {message}" if key else f"{file}: {message}")


@dataclass(frozen=True)
class Airframe:
    name: str
    path: Path
    airframe_class: str
    source: str
    notes: str
    #: Why no rigid body has this inertia (only seed 001's, which the plant exempts, can be so); ""
    #: otherwise
    inconsistent: str
    params: dict[str, float]
    sha256: str

    def describe(self) -> str:
        """One line for reports: the name, and for the seed's airframe that it is physically
        inconsistent."""
        said = self.name if not self.airframe_class else f"{self.name} ({self.airframe_class})"
        return f"{said}; physically inconsistent: {self.inconsistent}" if self.inconsistent else said


def shipped() -> list[str]:
    """The names of the airframes that come with the rig."""
    return sorted(p.stem for p in AIRFRAMES_DIR.glob("*.toml"))


def resolve(name_or_file: str | Path) -> Path:
    """A shipped airframe's name, or a path to a TOML file, as the file's path."""
    text = str(name_or_file)
    if text in shipped():
        return AIRFRAMES_DIR / f"{text}.toml"
    path = Path(text)
    if path.suffix == ".toml" or path.exists():
        return path
    close = difflib.get_close_matches(text, shipped(), n=1)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    raise AirframeError(text, "", f"no such airframe: expected a file or one of {', '.join(shipped())}"
                        + hint)


def load(name_or_file: str | Path = DEFAULT_AIRFRAME) -> Airframe:
    """Reads and checks one airframe (a shipped name or a file); raises AirframeError naming the file
    and key, never a traceback."""
    path = resolve(name_or_file)
    file = str(path)
    try:
        toml = read_toml(path)
    except TomlFileError as e:
        raise AirframeError(file, "", str(e)) from None
    return check(toml.data, path, toml.sha256)


def _unknown(file: str, table: str, keys: Any, known: tuple[str, ...]) -> None:
    for key in keys:
        if key not in known:
            close = difflib.get_close_matches(key, known, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else f"; expected one of {', '.join(known)}"
            raise AirframeError(file, f"{table}{key}", "unknown key" + hint)


def check(data: dict[str, Any], path: Path, sha256: str) -> Airframe:
    """Checks an airframe's parsed tables: known keys, a cited source, parameters the plant accepts."""
    file = str(path)
    _unknown(file, "", data, ("airframe", "params"))
    meta, params_raw = data.get("airframe"), data.get("params")
    if not isinstance(meta, dict):
        raise AirframeError(file, "airframe", "missing; expected an [airframe] table with name and source")
    if not isinstance(params_raw, dict):
        raise AirframeError(file, "params", "missing; expected a [params] table of plant parameters")
    _unknown(file, "airframe.", meta, _AIRFRAME_KEYS)
    for key in _REQUIRED:
        if key not in meta:
            why = " (an airframe cites where its numbers come from)" if key == "source" else ""
            raise AirframeError(file, f"airframe.{key}", "missing" + why)
    texts: dict[str, str] = {}
    for key in _AIRFRAME_KEYS:
        value = meta.get(key, "")
        if not isinstance(value, str):
            raise AirframeError(file, f"airframe.{key}", f"expected a string, got {value!r}")
        texts[key] = value.strip()
    for key in _REQUIRED:
        if not texts[key]:
            raise AirframeError(file, f"airframe.{key}", "empty")
    _unknown(file, "params.", params_raw, AIRFRAME_PARAMETERS)
    params: dict[str, float] = {}
    for key, value in params_raw.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise AirframeError(file, f"params.{key}", f"expected a number, got {value!r}")
        params[key] = float(value)
    refused = check_parameters(params)
    if refused:
        raise AirframeError(file, f"params.{refused.split()[0]}", f"the plant refuses it: {refused}")
    broken = triangle_broken(*(params.get(k, PARAMETERS[k].start) for k in ("Ixx", "Iyy", "Izz")))
    if broken and not texts["inconsistent"]:  # (seed 001's: the only inertia the plant lets through)
        raise AirframeError(file, "airframe.inconsistent",
                            f"missing; this inertia breaks the rule '{broken}', which the file must say")
    if texts["inconsistent"] and not broken:
        raise AirframeError(file, "airframe.inconsistent",
                            "this inertia is a rigid body's: remove the key")
    return Airframe(texts["name"], path, texts["class"], texts["source"], texts["notes"],
                    texts["inconsistent"], params, sha256)
