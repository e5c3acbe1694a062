"""The shipped config profiles (common/config/*.toml besides default.toml and schema.toml): each one validates
against the schema, and changes only the fields it documents, so it cannot drift from the defaults unnoticed."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from fuzzyctl.cli import main

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "common" / "config"

# profile -> the (section, field) pairs it may set, with their values
PROFILES = {
    "fast.toml": {("detect", "matcher_iterations"): 2, ("densify", "interpolate_max_diff"): 0},
    "accurate.toml": {("boundary", "enabled"): True},
}


def test_every_shipped_profile_is_listed_here():
    shipped = {p.name for p in CONFIG.glob("*.toml")} - {"default.toml", "schema.toml"}
    assert shipped == set(PROFILES)


@pytest.mark.parametrize("name", sorted(PROFILES))
def test_profile_validates_and_changes_only_its_fields(name, capsys):
    path = CONFIG / name
    assert main(["config", "check", str(path)]) == 0
    prof = tomllib.loads(path.read_text())
    default = tomllib.loads((CONFIG / "default.toml").read_text())
    fields = {(sec, key): val for sec, tbl in prof.items() for key, val in tbl.items()}
    assert fields == PROFILES[name]
    for (sec, key), val in fields.items():
        assert default[sec][key] != val, f"{name}: [{sec}] {key} equals the default"
