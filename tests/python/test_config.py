"""Config loading and validation against common/config/schema.toml."""

from __future__ import annotations

import tomllib

import pytest

from fuzzyctl import config as cfgmod
from fuzzyctl.errors import FatalError


def test_default_toml_satisfies_schema_and_sets_every_field(common_dir):
    schema = cfgmod.load_schema(common_dir / "config" / "schema.toml")
    with open(common_dir / "config" / "default.toml", "rb") as f:
        doc = tomllib.load(f)
    values = cfgmod.validate(doc, schema, "default.toml")  # raises on unknown/invalid
    for section, fields in schema.items():
        for name in fields:
            assert name in values.get(section, {}), f"default.toml has no {section}.{name}"
    # and nothing outside the schema
    assert set(doc) == set(schema)


def test_schema_entries_are_well_formed():
    schema = cfgmod.load_schema()
    for fields in schema.values():
        for spec in fields.values():
            if spec.type == "string":  # strings have choices (or are free text), no range
                assert spec.min is None and spec.max is None, spec.key
            elif spec.type != "bool":
                assert spec.min is not None and spec.max is not None, spec.key
                assert spec.min <= spec.max, spec.key
            assert spec.doc, f"{spec.key} has no doc"


def test_load_defaults(common_dir):
    with open(common_dir / "config" / "default.toml", "rb") as f:
        doc = tomllib.load(f)
    cfg = cfgmod.load_config()
    assert cfg.cost.max_disparity == doc["cost"]["max_disparity"]
    assert cfg.cost.alpha == doc["cost"]["alpha"] and isinstance(cfg.cost.alpha, float)
    assert cfg.esr.enabled is doc["esr"]["enabled"]
    assert cfg.get("esr.window") == doc["esr"]["window"]


def test_overlay_and_int_accepted_for_float(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text("[cost]\nmax_disparity = 32\nalpha = 1\n")
    cfg = cfgmod.load_config(p)
    assert cfg.cost.max_disparity == 32
    assert cfg.cost.alpha == 1.0 and isinstance(cfg.cost.alpha, float)
    assert cfg.segmentation.region_size == 8  # default kept


@pytest.mark.parametrize(
    "text, message",
    [
        ("[cost]\nmax_disparity = 300\n", r"c.toml: cost.max_disparity = 300 is out of range; expected an integer in \[2, 256\] px"),
        ("[cost]\nmax_disparity = 1\n", r"cost.max_disparity = 1 is out of range"),
        ("[cost]\nalpha = 1.5\n", r"cost.alpha = 1.5 is out of range; expected a number in \[0, 1\]"),
        ("[cost]\nmax_disparity = 64.0\n", r"cost.max_disparity = 64.0 is not an integer"),
        ("[cost]\nmax_disparity = \"64\"\n", r"cost.max_disparity = \"64\" is not a number"),
        ("[esr]\nwindow = 10\n", r"esr.window = 10 is not odd; expected an odd integer in \[3, 31\] px"),
        ("[esr]\nenabled = 1\n", r"esr.enabled = 1 is not a boolean; expected true or false"),
        ("[cost]\nmax_disparty = 64\n", r"unknown key cost.max_disparty \(keys of \[cost\]: max_disparity"),
        ("[costs]\nalpha = 0.5\n", r"unknown section \[costs\]"),
        ("[cost]\nalpha = \n", r"not valid TOML"),
        ("[lr_check]\nmax_diff = true\n", r"lr_check.max_diff = true is not a number"),
        ("[boundary]\nwindow = 4\n", r"boundary.window = 4 is not odd; expected an odd integer in \[1, 9\] px"),
        ("[boundary]\nmargin = -1\n", r"boundary.margin = -1.0 is out of range; expected a number in \[0, 24\] bits per window pixel"),
    ],
)
def test_invalid_configs_name_the_field_and_range(tmp_path, text, message):
    p = tmp_path / "c.toml"
    p.write_text(text)
    with pytest.raises(FatalError, match=message):
        cfgmod.load_config(p)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(FatalError, match=r"cannot read .*none.toml"):
        cfgmod.load_config(tmp_path / "none.toml")


def test_round_trip_through_toml_text():
    cfg = cfgmod.load_config()
    again = cfgmod.parse_config(cfg.to_toml(), "roundtrip")
    assert again == cfg


def test_non_strict_ignores_unknown_keys_with_warning():
    text = "[cost]\ninject_shift = 3\nmax_disparity = 16\n"
    with pytest.raises(FatalError):
        cfgmod.parse_config(text, "dump")
    with pytest.warns(UserWarning, match="inject_shift"):
        cfg = cfgmod.parse_config(text, "dump", strict=False)
    assert cfg.cost.max_disparity == 16


def test_common_dir_from_environment(tmp_path, monkeypatch):
    from fuzzyctl import paths

    monkeypatch.setenv("FUZZYSTEREO_COMMON", str(tmp_path / "nowhere"))
    with pytest.raises(FatalError, match="FUZZYSTEREO_COMMON"):
        paths.common_dir()
    (tmp_path / "c" / "config").mkdir(parents=True)
    monkeypatch.setenv("FUZZYSTEREO_COMMON", str(tmp_path / "c"))
    with pytest.raises(FatalError, match=r"missing shared definition file .*schema.toml"):
        paths.schema_file()
