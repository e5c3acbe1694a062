"""The matcher configuration: TOML, validated once against ``common/config/schema.toml``.

The schema is shared with the firmware (``firmware/config``), so a range is written once. Each
schema entry ``[section.field]`` has ``type`` (``int`` | ``float`` | ``bool``), optional inclusive
``min``/``max``, ``odd = true`` for odd integers, and ``doc``/``unit`` used in messages.

``load_config(path)`` = ``common/config/default.toml`` overlaid with the file at ``path``; unknown
sections or keys, wrong types and out-of-range values raise :class:`FatalError` with a message
naming the field and its valid range. Per-frame code (the reference) assumes a valid config.
"""

from __future__ import annotations

import copy
import tomllib
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from . import paths
from .errors import FatalError

_TYPES = {"int": int, "float": float, "bool": bool, "string": str}


@dataclass(frozen=True)
class FieldSpec:
    section: str
    name: str
    type: str
    min: float | None = None
    max: float | None = None
    odd: bool = False
    choices: tuple[str, ...] = ()
    unit: str = ""
    doc: str = ""

    @property
    def key(self) -> str:
        return f"{self.section}.{self.name}"

    def range_text(self) -> str:
        if self.type == "bool":
            return "true or false"
        if self.type == "string":
            return "one of " + ", ".join(repr(c) for c in self.choices) if self.choices else "a string"
        lo = "-inf" if self.min is None else _fmt(self.min)
        hi = "inf" if self.max is None else _fmt(self.max)
        text = f"{'an odd integer' if self.odd else 'an integer' if self.type == 'int' else 'a number'} in [{lo}, {hi}]"
        return text + (f" {self.unit}" if self.unit else "")

    def check(self, value: Any, source: str) -> Any:
        """The value converted to the field's Python type; FatalError naming the field otherwise."""

        def bad(why: str) -> FatalError:
            doc = f" ({self.doc})" if self.doc else ""
            return FatalError(f"{source}: {self.key} = {_show(value)} {why}; expected {self.range_text()}{doc}")

        if self.type == "bool":
            if not isinstance(value, bool):
                raise bad("is not a boolean")
            return value
        if self.type == "string":
            if not isinstance(value, str):
                raise bad("is not a string")
            if self.choices and value not in self.choices:
                raise bad("is not a valid choice")
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise bad("is not a number")
        if self.type == "int":
            if not isinstance(value, int):
                raise bad("is not an integer")
        else:
            value = float(value)
        if (self.min is not None and value < self.min) or (self.max is not None and value > self.max):
            raise bad("is out of range")
        if self.odd and value % 2 == 0:
            raise bad("is not odd")
        return value


def _fmt(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else repr(float(v))


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    return repr(value)


# ---- schema -------------------------------------------------------------------------------------


def load_schema(path: str | Path | None = None) -> dict[str, dict[str, FieldSpec]]:
    """``{section: {field: FieldSpec}}`` from the schema file (default: common/config/schema.toml)."""
    path = Path(path) if path is not None else paths.schema_file()
    doc = _read_toml(path)
    schema: dict[str, dict[str, FieldSpec]] = {}
    for section, fields in doc.items():
        if not isinstance(fields, dict):
            raise FatalError(f"{path}: [{section}] must be a table of fields")
        for name, spec in fields.items():
            key = f"{section}.{name}"
            if not isinstance(spec, dict) or spec.get("type") not in _TYPES:
                raise FatalError(f"{path}: [{key}] needs type = \"int\" | \"float\" | \"bool\" | \"string\"")
            extra = sorted(set(spec) - {"type", "min", "max", "odd", "choices", "unit", "doc"})
            if extra:
                raise FatalError(f"{path}: [{key}] has unknown schema key(s) {', '.join(extra)}")
            schema.setdefault(section, {})[name] = FieldSpec(
                section=section,
                name=name,
                type=spec["type"],
                min=spec.get("min"),
                max=spec.get("max"),
                odd=bool(spec.get("odd", False)),
                choices=tuple(str(c) for c in spec.get("choices", ())),
                unit=str(spec.get("unit", "")),
                doc=str(spec.get("doc", "")),
            )
    return schema


def _read_toml(path: Path) -> dict:
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except OSError as exc:
        raise FatalError(f"cannot read {path}: {exc.strerror}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise FatalError(f"{path}: not valid TOML: {exc}") from exc


# ---- config -------------------------------------------------------------------------------------


class Section:
    """Read-only attribute view of one config section (``cfg.cost.max_disparity``)."""

    def __init__(self, name: str, values: dict[str, Any]):
        object.__setattr__(self, "_name", name)
        object.__setattr__(self, "_values", dict(values))

    def __getattr__(self, key: str) -> Any:
        try:
            return self._values[key]
        except KeyError:
            raise AttributeError(f"config section [{self._name}] has no field '{key}'") from None

    def __setattr__(self, key: str, value: Any) -> None:
        raise AttributeError("config is read-only")

    def as_dict(self) -> dict[str, Any]:
        return dict(self._values)

    def __repr__(self) -> str:
        return f"Section({self._name}, {self._values})"


class Config:
    """A validated, complete configuration (every schema field present)."""

    def __init__(self, values: dict[str, dict[str, Any]], source: str = "<defaults>"):
        self._values = copy.deepcopy(values)
        self.source = source

    def __getattr__(self, section: str) -> Section:
        if section.startswith("_"):
            raise AttributeError(section)
        try:
            return Section(section, self._values[section])
        except KeyError:
            raise AttributeError(f"config has no section [{section}]") from None

    def get(self, key: str) -> Any:
        section, name = key.split(".", 1)
        return self._values[section][name]

    def as_dict(self) -> dict[str, dict[str, Any]]:
        return copy.deepcopy(self._values)

    def to_toml(self) -> str:
        return dumps_toml(self._values)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Config) and other._values == self._values

    def __repr__(self) -> str:
        return f"Config({self.source})"


def dumps_toml(values: dict[str, dict[str, Any]]) -> str:
    """Flat two-level TOML text (``[section]`` then ``key = value``), as the firmware writes it."""
    lines: list[str] = []
    for section, fields in values.items():
        if lines:
            lines.append("")
        lines.append(f"[{section}]")
        for key, value in fields.items():
            if isinstance(value, bool):
                text = "true" if value else "false"
            elif isinstance(value, float):
                text = repr(value)
            elif isinstance(value, str):
                text = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'

            else:
                text = str(value)
            lines.append(f"{key} = {text}")
    return "\n".join(lines) + "\n"


def validate(
    doc: dict,
    schema: dict[str, dict[str, FieldSpec]],
    source: str,
    base: dict[str, dict[str, Any]] | None = None,
    strict: bool = True,
    ignored: dict[str, Any] | None = None,
) -> dict[str, dict[str, Any]]:
    """``base`` (or nothing) overlaid with ``doc``, every value checked against ``schema``.

    With ``strict=False`` unknown sections/keys are skipped instead of failing — collected in
    ``ignored`` (``{"section.key": value}``) when given, else warned about. Used for configs
    recorded in firmware dumps, which carry test-only keys (``[testing] inject_shift``).
    """
    out = copy.deepcopy(base) if base is not None else {}

    def skip(msg: str, key: str, value: Any) -> None:
        if strict:
            raise FatalError(msg)
        if ignored is not None:
            ignored[key] = value
        else:
            warnings.warn(msg, stacklevel=3)

    for section, fields in doc.items():
        if section not in schema:
            msg = f"{source}: unknown section [{section}] (sections: {', '.join(schema)})"
            if isinstance(fields, dict) and fields:
                for name, value in fields.items():
                    skip(msg, f"{section}.{name}", value)
            else:
                skip(msg, section, fields)
            continue
        if not isinstance(fields, dict):
            raise FatalError(f"{source}: '{section}' must be a table [{section}]")
        for name, value in fields.items():
            spec = schema[section].get(name)
            if spec is None:
                skip(f"{source}: unknown key {section}.{name} (keys of [{section}]: {', '.join(schema[section])})",
                     f"{section}.{name}", value)
                continue
            out.setdefault(section, {})[name] = spec.check(value, source)
    return out


def _missing(values: dict, schema: dict[str, dict[str, FieldSpec]]) -> list[str]:
    return [f"{s}.{n}" for s, fields in schema.items() for n in fields if n not in values.get(s, {})]


def default_values(schema: dict[str, dict[str, FieldSpec]] | None = None) -> dict[str, dict[str, Any]]:
    """The validated ``common/config/default.toml``; it must set every schema field."""
    schema = schema if schema is not None else load_schema()
    path = paths.default_config_file()
    values = validate(_read_toml(path), schema, str(path))
    missing = _missing(values, schema)
    if missing:
        raise FatalError(f"{path}: no default for {', '.join(missing)}")
    # schema order, so dumps and `fuzzyctl config` list fields the same way every time
    return {s: {n: values[s][n] for n in fields} for s, fields in schema.items()}


def load_config(path: str | Path | None = None) -> Config:
    """Defaults overlaid with the TOML file at ``path`` (None: defaults only)."""
    schema = load_schema()
    base = default_values(schema)
    if path is None:
        return Config(base)
    path = Path(path)
    values = validate(_read_toml(path), schema, str(path), base=base)
    return Config(values, str(path))


def parse_config(
    text: str, source: str = "<string>", strict: bool = True, ignored: dict[str, Any] | None = None
) -> Config:
    """Defaults overlaid with TOML text (e.g. a dump's ``config_toml``); see :func:`validate`."""
    schema = load_schema()
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise FatalError(f"{source}: not valid TOML: {exc}") from exc
    values = validate(doc, schema, source, base=default_values(schema), strict=strict, ignored=ignored)
    return Config(values, source)
