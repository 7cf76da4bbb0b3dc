"""A sweep spec (docs/sweeps.md): one scenario, the keys it varies and the seeds, expanded into variants,
each checked by the scenario checker before anything runs.

    [sweep]
    scenario = "step_roll"          # a library name or a file (relative to the spec)
    seeds = 10                      # seeds 0..9, or a list
    mode = "grid"                   # or "random" with samples = N and seed = S (the draws' own)

    [[sweep.vary]]
    key = "vehicle.mass"            # a scenario key path: environment.wind, faults[0].start, fc.rate_kp
    values = [1.1, 1.2, 1.3]        # or, in random mode, uniform = [lo, hi] or normal = [mu, sigma]

A variant is the scenario's tables with each key set, and a seed. Its id is a hash of exactly that (and
of the scenario file's content), so a spec run again into the same folder finds what it already ran
(and a spec given more seeds or values runs only the new ones).
This layer only reads and expands; rig/sweep runs."""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import random
import re
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.plant import airframes
from rig.plant.toml_file import TomlFileError, read_toml
from rig.scenarios.schema import Scenario, ScenarioError, check

SWEEP_KEYS = {"scenario", "seeds", "mode", "samples", "seed", "vary"}
VARY_KEYS = {"key", "values", "uniform", "normal"}
MODES = ("grid", "random")
#: more variants than this is a typo more often than a plan (a grid multiplies)
MAX_VARIANTS = 1_000_000
_SEGMENT = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)$")


class SweepError(ValueError):
    """A spec that cannot be run: where (the spec's key, or a variant) and why."""

    def __init__(self, where: str, message: str) -> None:
        self.where = where
        super().__init__(f"{where}: {message}" if where else message)


@dataclass(frozen=True)
class Vary:
    key: str
    values: tuple[Any, ...] = ()  # grid (or random: drawn from these)
    uniform: tuple[float, float] | None = None  # random mode
    normal: tuple[float, float] | None = None  # random mode


@dataclass(frozen=True)
class Variant:
    """One run of the sweep: the scenario's tables with ``values`` set, flown with ``seed``."""

    index: int
    id: str
    values: dict[str, Any]
    seed: int
    data: dict[str, Any]  # the scenario's tables, varied (what a worker checks and flies)


@dataclass(frozen=True)
class Sweep:
    path: Path
    scenario_path: Path
    scenario: Scenario  # the nominal one
    mode: str
    seeds: tuple[int, ...]
    vary: tuple[Vary, ...]
    samples: int
    draw_seed: int
    variants: tuple[Variant, ...]
    sha256: str  # of the spec and the scenario file (informational: runs are found by their ids)

    @property
    def columns(self) -> list[str]:
        return [v.key for v in self.vary]  # (a column is named by its key path)


def parse_key(key: str) -> list[str | int]:
    """``faults[0].start`` -> ["faults", 0, "start"]."""
    out: list[str | int] = []
    for part in key.split("."):
        m = _SEGMENT.match(part)
        if not m:
            raise ValueError(f"{key!r} is not a key path (names joined by '.', list items as [N])")
        out.append(m.group(1))
        out += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    return out


def set_key(data: dict[str, Any], key: str, value: Any) -> None:
    """Sets ``key`` in the scenario's tables: a missing table or key is created (the checker then says
    whether the scenario may have it); a list item must exist."""
    path = parse_key(key)
    node: Any = data
    for i, part in enumerate(path[:-1]):
        nxt = path[i + 1]
        if isinstance(part, int):
            if not isinstance(node, list) or part >= len(node):
                raise ValueError(
                    f"{key}: the scenario has no item {part} there "
                    f"({len(node) if isinstance(node, list) else 0} items)"
                )
            node = node[part]
            continue
        if not isinstance(node, dict):
            raise ValueError(f"{key}: {part!r} is inside a value that is not a table")
        if part not in node:
            if isinstance(nxt, int):
                raise ValueError(f"{key}: the scenario has no {part!r} list to index")
            node[part] = {}
        node = node[part]
    last = path[-1]
    if isinstance(last, int):
        if not isinstance(node, list) or last >= len(node):
            raise ValueError(f"{key}: the scenario has no item {last} there")
        node[last] = value
    elif isinstance(node, dict):
        node[last] = value
    else:
        raise ValueError(f"{key}: {last!r} is inside a value that is not a table")


def _number_pair(v: Any, where: str) -> tuple[float, float]:
    if (
        not isinstance(v, list)
        or len(v) != 2
        or not all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) for x in v)
    ):
        raise SweepError(where, f"expected two finite numbers, got {v!r}")
    return float(v[0]), float(v[1])


def _vary(raw: Any, i: int, mode: str) -> Vary:
    where = f"sweep.vary[{i}]"
    if not isinstance(raw, dict):
        raise SweepError(where, "expected a table ([[sweep.vary]] with key and values)")
    unknown = set(raw) - VARY_KEYS
    if unknown:
        raise SweepError(
            where, f"unknown key(s) {', '.join(sorted(unknown))}; known: {', '.join(sorted(VARY_KEYS))}"
        )
    key = raw.get("key")
    if not isinstance(key, str):
        raise SweepError(
            f"{where}.key", "missing; expected the scenario key path to vary (e.g. vehicle.mass)"
        )
    try:
        parse_key(key)
    except ValueError as e:
        raise SweepError(f"{where}.key", str(e)) from None
    given = [k for k in ("values", "uniform", "normal") if k in raw]
    if len(given) != 1:
        raise SweepError(
            where, f"give exactly one of values, uniform, normal (got {', '.join(given) or 'none'})"
        )
    if "values" in raw:
        values = raw["values"]
        if not isinstance(values, list) or not values:
            raise SweepError(f"{where}.values", "expected a non-empty list")
        return Vary(key, values=tuple(values))
    if mode != "random":
        raise SweepError(f"{where}.{given[0]}", 'a distribution needs mode = "random" (a grid needs values)')
    if "uniform" in raw:
        lo, hi = _number_pair(raw["uniform"], f"{where}.uniform")
        if not lo < hi:
            raise SweepError(f"{where}.uniform", f"expected [lo, hi] with lo < hi, got {raw['uniform']}")
        return Vary(key, uniform=(lo, hi))
    mu, sigma = _number_pair(raw["normal"], f"{where}.normal")
    if not sigma > 0:
        raise SweepError(f"{where}.normal", f"expected [mu, sigma] with sigma > 0, got {raw['normal']}")
    return Vary(key, normal=(mu, sigma))


def _seeds(raw: Any) -> tuple[int, ...]:
    if isinstance(raw, bool) or raw is None:
        raise SweepError("sweep.seeds", f"expected a count or a list of seeds, got {raw!r}")
    if isinstance(raw, int):
        if not 1 <= raw <= 100_000:
            raise SweepError("sweep.seeds", f"expected a count in 1..100000, got {raw}")
        return tuple(range(raw))
    if (
        isinstance(raw, list)
        and raw
        and all(isinstance(s, int) and not isinstance(s, bool) and 0 <= s < 2**32 for s in raw)
    ):
        if len(set(raw)) != len(raw):
            raise SweepError("sweep.seeds", "a seed is listed twice")
        return tuple(raw)
    raise SweepError("sweep.seeds", f"expected a count or a non-empty list of seeds 0..2^32-1, got {raw!r}")


def variant_id(scenario_sha: str, values: dict[str, Any], seed: int, sample: int | None = None) -> str:
    """What a run is: the scenario's content, the values set, the seed (and a random sweep's draw number:
    two draws of a list may pick the same values)."""
    blob = json.dumps([scenario_sha, sorted(values.items()), seed, sample], sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:12]


def _draw(v: Vary, rng: random.Random) -> Any:
    if v.uniform is not None:
        return rng.uniform(*v.uniform)
    if v.normal is not None:
        return rng.gauss(*v.normal)
    return rng.choice(v.values)


def load_sweep(path: str | Path, library: Path, resolve: Callable[[str], Path | None] | None = None,
               airframe: str | None = None) -> Sweep:
    """Reads a spec, expands its variants and checks each one; SweepError names the first problem
    (a variant's is the scenario checker's message with the values that made it). ``resolve`` finds
    a scenario by name instead of ``library`` (the service's: the library and the uploads), and then
    a file path is not accepted (a spec from a request names no file). ``airframe`` (``--airframe``)
    replaces the scenario's [vehicle] airframe in every variant (a file: its absolute path)."""
    path = Path(path)
    try:
        toml = read_toml(path)
        spec, raw = toml.data, toml.raw
    except TomlFileError as e:
        raise SweepError(str(path), str(e)) from None
    if set(spec) != {"sweep"}:
        raise SweepError(
            str(path), "expected one [sweep] table (and its [[sweep.vary]] tables), nothing else"
        )
    s = spec["sweep"]
    unknown = set(s) - SWEEP_KEYS
    if unknown:
        raise SweepError(
            "sweep", f"unknown key(s) {', '.join(sorted(unknown))}; known: {', '.join(sorted(SWEEP_KEYS))}"
        )
    name = s.get("scenario")
    if not isinstance(name, str) or not name:
        raise SweepError("sweep.scenario", "missing; expected a library name or a scenario file")
    if resolve is not None:
        found = resolve(name)
        if found is None:
            raise SweepError("sweep.scenario", f"no scenario named {name!r} (the library or an upload)")
        scenario_path = found
    else:
        scenario_path = (path.parent / name) if name.endswith(".toml") else library / f"{name}.toml"
        if not scenario_path.is_file():
            raise SweepError("sweep.scenario", f"no scenario {name!r} (not a file, nor in {library})")
    mode = s.get("mode", "grid")
    if mode not in MODES:
        raise SweepError("sweep.mode", f"expected one of {', '.join(MODES)}, got {mode!r}")
    seeds = _seeds(s.get("seeds", 1))
    vary_raw = s.get("vary", [])
    if not isinstance(vary_raw, list):
        raise SweepError("sweep.vary", "expected [[sweep.vary]] tables")
    vary = tuple(_vary(v, i, mode) for i, v in enumerate(vary_raw))
    keys = [v.key for v in vary]
    if len(set(keys)) != len(keys):
        raise SweepError("sweep.vary", "a key is varied twice")
    samples, draw_seed = 0, 0
    if mode == "random":
        samples = s.get("samples")
        if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= MAX_VARIANTS:
            raise SweepError(
                "sweep.samples", f"random mode needs samples = N (1..{MAX_VARIANTS}), got {samples!r}"
            )
        draw_seed = s.get("seed", 0)
        if isinstance(draw_seed, bool) or not isinstance(draw_seed, int):
            raise SweepError("sweep.seed", f"expected an integer (the draws' own seed), got {draw_seed!r}")
    elif "samples" in s or "seed" in s:
        raise SweepError("sweep", "samples and seed are random mode's (grid runs every combination)")

    try:
        nominal_raw = scenario_path.read_bytes()
        nominal = tomllib.loads(nominal_raw.decode("utf-8"))
        if airframe is not None:  # (part of what the runs are: their ids and the sweep's hash change)
            flown = airframe if airframe in airframes.shipped() else str(Path(airframe).resolve())
            nominal.setdefault("vehicle", {})["airframe"] = flown
            nominal_raw += b"\0airframe=" + flown.encode()
        scenario = check(nominal, scenario_path, hashlib.sha256(nominal_raw).hexdigest())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise SweepError("sweep.scenario", f"{scenario_path}: {e}") from None
    except ScenarioError as e:
        raise SweepError("sweep.scenario", str(e)) from None

    if mode == "grid":
        count = math.prod(len(v.values) for v in vary) * len(seeds)
        if count > MAX_VARIANTS:
            raise SweepError("sweep", f"{count} runs in the grid; at most {MAX_VARIANTS}")
        combos = [dict(zip(keys, c, strict=True)) for c in itertools.product(*(v.values for v in vary))]
    else:
        if samples * len(seeds) > MAX_VARIANTS:
            raise SweepError("sweep", f"{samples * len(seeds)} runs; at most {MAX_VARIANTS}")
        rng = random.Random(draw_seed)
        combos = [{v.key: _draw(v, rng) for v in vary} for _ in range(samples)]

    variants: list[Variant] = []
    checked: dict[str, None] = {}
    for n, combo in enumerate(combos):
        data = copy.deepcopy(nominal)
        label = ", ".join(f"{k} = {json.dumps(v)}" for k, v in combo.items()) or "the nominal scenario"
        try:
            for k, v in combo.items():
                set_key(data, k, v)
        except ValueError as e:
            raise SweepError(f"variant {label}", str(e)) from None
        key = json.dumps(combo, sort_keys=True, default=str)
        if key not in checked:  # (seeds share a check)
            try:
                check(data, scenario_path)
            except ScenarioError as e:
                raise SweepError(f"variant {label}", str(e)) from None
            checked[key] = None
        for seed in seeds:
            sample = n if mode == "random" else None
            variants.append(
                Variant(len(variants), variant_id(scenario.sha256, combo, seed, sample), combo, seed, data)
            )
    ids = [v.id for v in variants]
    if len(set(ids)) != len(ids):
        raise SweepError("sweep.vary", "two variants are the same run (a value listed twice?)")
    sha = hashlib.sha256(raw + b"\0" + scenario.sha256.encode()).hexdigest()
    return Sweep(path, scenario_path, scenario, mode, seeds, vary, samples, draw_seed, tuple(variants), sha)
