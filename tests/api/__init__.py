"""The public API (rig/api.py) and the pytest plugin (rig/pytest_plugin.py)."""

from pathlib import Path

LIBRARY = Path(__file__).resolve().parents[2] / "scenarios" / "library"
#: the shortest library scenario: 8 s of sim time, about a second of wall time in lockstep
SHORT = LIBRARY / "seed000_roll_stand.toml"


def failing_copy(folder: Path, stem: str = "roll_stand_too_strict") -> Path:
    """seed000_roll_stand with an overshoot limit the reference FC cannot meet (0.001 deg)."""
    text = SHORT.read_text()
    assert "max = 25.0" in text
    path = folder / f"{stem}.toml"
    path.write_text(text.replace("max = 25.0", "max = 0.001"))
    return path
