"""Every TOML file kind the rig reads (scenario, sweep, airframe, FC profile, board) says the same three
things the same way: a file that cannot be read, bytes that are not UTF-8 (TOML is UTF-8 text, toml.io
§Spec), and TOML that does not parse; each names the file, none is a traceback."""

from collections.abc import Callable
from pathlib import Path

import pytest

from rig.mcu import board
from rig.plant import airframes
from rig.scenarios import profile, schema, sweep

LOADERS: dict[str, Callable[[Path], object]] = {
    "scenario": schema.load,
    "sweep": lambda p: sweep.load_sweep(p, p.parent),
    "airframe": airframes.load,
    "profile": profile.load,
    "board": board.load,
}


@pytest.mark.parametrize("kind", LOADERS)
@pytest.mark.parametrize(("content", "said"), [
    (b"name = \"caf\xe9\"\n",  # é in Latin-1: 0xe9 at offset 11 starts a sequence the quote cannot continue
     "not valid TOML: not UTF-8 text (invalid continuation byte at offset 11)"),
    (b"[unclosed\n", "not valid TOML: "),
])
def test_each_file_kind_says_why_it_cannot_be_read(kind: str, content: bytes, said: str,
                                                   tmp_path: Path) -> None:
    path = tmp_path / f"bad-{kind}.toml"
    path.write_bytes(content)
    with pytest.raises(ValueError) as caught:
        LOADERS[kind](path)
    assert said in str(caught.value) and str(path) in str(caught.value)


@pytest.mark.parametrize("kind", ["scenario", "sweep", "airframe"])
def test_a_folder_is_not_a_file_it_can_read(kind: str, tmp_path: Path) -> None:
    (tmp_path / "dir.toml").mkdir()
    with pytest.raises(ValueError, match="cannot read: Is a directory"):
        LOADERS[kind](tmp_path / "dir.toml")
