#!/usr/bin/env python3
"""Generate the C++ codec of the serial link from common/protocol/protocol.toml.

Python standard library only (tomllib, Python >= 3.11): CMake runs it at build time
(add_custom_command) and writes the header into the build tree. The layout hash computed here
(``schema_hash``) is the same function as host/src/fuzzyctl/link/schema.py uses; a test checks
both against common/protocol/vectors.toml.

usage: gen_cpp.py protocol.toml OUT.hpp
"""

from __future__ import annotations

import hashlib
import json
import sys
import tomllib

CPP_TYPES = {"u8": "std::uint8_t", "u16": "std::uint16_t", "u32": "std::uint32_t", "i32": "std::int32_t",
             "f32": "float", "str": "std::string", "bytes": "std::vector<std::uint8_t>"}
SCALARS = {"u8", "u16", "u32", "i32", "f32"}


# The layout hash is computed a second time, independently, by the host
# (fuzzyctl.link.schema.layout_hash): this generator runs at build time with the bare system Python
# (also for the cross build) and must not import the host package. The two must agree byte for byte;
# tests/python/test_link_device.py::test_info_reports_layout_and_config checks the firmware's
# generated hash against the host's.
def _strip_docs(node):
    if isinstance(node, dict):
        return {k: _strip_docs(v) for k, v in node.items() if k != "doc"}
    if isinstance(node, list):
        return [_strip_docs(v) for v in node]
    return node


def schema_hash(schema: dict) -> bytes:
    """First 8 bytes of SHA-256 of the canonical JSON of the schema without `doc` keys."""
    canon = json.dumps(_strip_docs(schema), sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(canon.encode("utf-8")).digest()[:8]


def camel(name: str) -> str:
    return "".join(p.capitalize() for p in name.split("_"))


def _check(schema: dict) -> None:
    ids, names = set(), set()
    for m in schema["message"]:
        if m["id"] in ids or m["name"] in names:
            raise SystemExit(f"gen_cpp: duplicate message id/name {m['id']:#x} {m['name']}")
        ids.add(m["id"])
        names.add(m["name"])
    for owner, fields in [(m["name"], m["fields"]) for m in schema["message"]] + \
                         [(n, s["fields"]) for n, s in schema.get("structs", {}).items()]:
        for f in fields:
            t = f["type"]
            if t == "array":
                if f.get("struct") not in schema.get("structs", {}) or "max" not in f:
                    raise SystemExit(f"gen_cpp: {owner}.{f['name']}: array needs a known struct and max")
            elif t not in CPP_TYPES:
                raise SystemExit(f"gen_cpp: {owner}.{f['name']}: unknown type {t}")


def _lit(t: str, v) -> str:
    if t == "f32":
        return f"{float(v)!r}f".replace("inff", "INFINITY")
    return str(int(v))


def _fields_code(type_name: str, fields: list[dict]) -> list[str]:
    out = []
    # encode
    out.append(f"inline bool encode(const {type_name}& m, Writer& w) {{")
    out.append("  (void)m;")
    for f in fields:
        n, t = f["name"], f["type"]
        if t == "array":
            out.append(f"  if (m.{n}.size() > {f['max']}) return false;")
            out.append(f"  w.u8(static_cast<std::uint8_t>(m.{n}.size()));")
            out.append(f"  for (const auto& e : m.{n}) if (!encode(e, w)) return false;")
        else:
            out.append(f"  w.{t}(m.{n});")
    out.append("  return w.ok();")
    out.append("}")
    # decode
    out.append(f"inline bool decode(Reader& r, {type_name}& m) {{")
    out.append("  (void)r; (void)m;")
    for f in fields:
        n, t = f["name"], f["type"]
        if t == "array":
            out.append("  {")
            out.append("    std::uint8_t count = 0;")
            out.append(f"    if (!r.u8(count) || count > {f['max']}) return false;")
            out.append(f"    m.{n}.resize(count);")
            out.append(f"    for (auto& e : m.{n}) if (!decode(r, e)) return false;")
            out.append("  }")
        else:
            out.append(f"  if (!r.{t}(m.{n})) return false;")
            if t in SCALARS and ("min" in f or "max" in f):
                conds = []
                if "min" in f and not (t != "i32" and t != "f32" and f["min"] <= 0):  # unsigned >= 0 always
                    conds.append(f"m.{n} >= {_lit(t, f['min'])}")
                if "max" in f:
                    conds.append(f"m.{n} <= {_lit(t, f['max'])}")
                if conds:
                    out.append(f"  if (!({' && '.join(conds)})) return false;  // valid range")
            elif t == "f32":
                out.append(f"  if (!std::isfinite(m.{n})) return false;")
    out.append("  return true;")
    out.append("}")
    # describe
    out.append(f"inline void describe(const {type_name}& m, std::string& s) {{")
    out.append("  (void)m;")
    out.append("  s += '{';")
    for i, f in enumerate(fields):
        n, t = f["name"], f["type"]
        sep = "," if i else ""
        out.append(f"  s += \"{sep}{n}=\";")
        if t == "array":
            out.append("  s += '[';")
            out.append(f"  for (std::size_t i = 0; i < m.{n}.size(); ++i) {{ if (i) s += ','; describe(m.{n}[i], s); }}")
            out.append("  s += ']';")
        else:
            out.append(f"  describe_value(m.{n}, s);")
    out.append("  s += '}';")
    out.append("}")
    return out


def generate(schema: dict) -> str:
    _check(schema)
    h = schema_hash(schema)
    proto = schema["protocol"]
    L = []
    L.append("// GENERATED by common/protocol/gen_cpp.py from common/protocol/protocol.toml — do not edit.")
    L.append("#pragma once")
    L.append("#include <array>\n#include <cmath>\n#include <cstdint>\n#include <string>\n#include <vector>\n")
    L.append('#include "fuzzystereo/link/wire.hpp"\n')
    L.append("namespace fs::link::msg {\n")
    L.append(f"inline constexpr std::array<std::uint8_t, 8> kSchemaHash = {{{', '.join(f'0x{b:02x}' for b in h)}}};")
    L.append(f'inline constexpr const char* kSchemaHashHex = "{h.hex()}";')
    L.append(f"inline constexpr std::size_t kMaxPayload = {int(proto['max_payload'])};")
    L.append(f"inline constexpr int kProtocolVersion = {int(proto['version'])};\n")
    for ename, values in schema.get("enums", {}).items():
        L.append(f"enum class {camel(ename)} : std::uint8_t {{")
        for k, v in values.items():
            if k != "doc":
                L.append(f"  {k} = {int(v)},")
        L.append("};")
        L.append(f"inline const char* to_string({camel(ename)} v) {{")
        L.append("  switch (v) {")
        for k, v in values.items():
            if k != "doc":
                L.append(f'    case {camel(ename)}::{k}: return "{k}";')
        L.append("  }")
        L.append('  return "?";')
        L.append("}\n")
    for sname, s in schema.get("structs", {}).items():
        L.append(f"struct {camel(sname)} {{")
        for f in s["fields"]:
            L.append(f"  {CPP_TYPES[f['type']]} {f['name']}{{}};" + (f"  // [{f['unit']}]" if "unit" in f else ""))
        L.append("};")
        L += _fields_code(camel(sname), s["fields"])
        L.append("")
    for m in schema["message"]:
        cn = camel(m["name"])
        L.append(f"struct {cn} {{")
        L.append(f"  static constexpr std::uint8_t kId = 0x{m['id']:02x};")
        L.append(f'  static constexpr const char* kName = "{m["name"]}";')
        for f in m["fields"]:
            t = f"std::vector<{camel(f['struct'])}>" if f["type"] == "array" else CPP_TYPES[f["type"]]
            L.append(f"  {t} {f['name']}{{}};" + (f"  // [{f['unit']}]" if "unit" in f else ""))
        L.append("};")
        L += _fields_code(cn, m["fields"])
        L.append("")
    L.append("inline const char* message_name(std::uint8_t id) {")
    L.append("  switch (id) {")
    for m in schema["message"]:
        L.append(f'    case 0x{m["id"]:02x}: return "{m["name"]}";')
    L.append("  }")
    L.append("  return nullptr;")
    L.append("}\n")
    L.append("// Decode a payload of message `id` (all bytes must be consumed) and describe it in the canonical")
    L.append("// text form shared with the Python codec. False for an unknown id or a malformed payload.")
    L.append("inline bool describe_payload(std::uint8_t id, const std::uint8_t* data, std::size_t n, std::string& out) {")
    L.append("  Reader r(data, n);")
    L.append("  switch (id) {")
    for m in schema["message"]:
        cn = camel(m["name"])
        L.append(f"    case 0x{m['id']:02x}: {{ {cn} m; if (!decode(r, m) || !r.at_end()) return false;"
                 f' out = "{m["name"]}"; describe(m, out); return true; }}')
    L.append("  }")
    L.append("  return false;")
    L.append("}\n")
    L.append("// Re-encode a payload of message `id` after decoding it (round trip); false as above.")
    L.append("inline bool reencode_payload(std::uint8_t id, const std::uint8_t* data, std::size_t n, std::vector<std::uint8_t>& out) {")
    L.append("  Reader r(data, n);")
    L.append("  out.clear();")
    L.append("  Writer w(out);")
    L.append("  switch (id) {")
    for m in schema["message"]:
        cn = camel(m["name"])
        L.append(f"    case 0x{m['id']:02x}: {{ {cn} m; if (!decode(r, m) || !r.at_end()) return false; return encode(m, w); }}")
    L.append("  }")
    L.append("  return false;")
    L.append("}\n")
    L.append("}  // namespace fs::link::msg")
    return "\n".join(L) + "\n"


def main(argv: list[str]) -> int:
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    with open(argv[1], "rb") as f:
        schema = tomllib.load(f)
    text = generate(schema)
    with open(argv[2], "w", encoding="utf-8") as f:
        f.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
