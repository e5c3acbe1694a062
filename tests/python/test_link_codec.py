"""The Python link codec against the shared vectors (common/protocol/vectors.toml, also checked by
tests/cpp/link), the generator's layout hash, and property tests on random/mutated frames."""

from __future__ import annotations

import importlib.util
import tomllib

import pytest

pytest.importorskip("cobs")
pytest.importorskip("google_crc32c")

from fuzzyctl.link.framing import FrameDecoder, crc32c, encode_frame  # noqa: E402
from fuzzyctl.link.schema import CodecError, load_schema  # noqa: E402


@pytest.fixture(scope="module")
def vectors(common_dir):
    with open(common_dir / "protocol" / "vectors.toml", "rb") as f:
        return tomllib.load(f)


@pytest.fixture(scope="module")
def schema():
    return load_schema()


def test_layout_hash_same_as_generator(schema, vectors, common_dir):
    spec = importlib.util.spec_from_file_location("gen_cpp", common_dir / "protocol" / "gen_cpp.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    assert gen.schema_hash(schema.raw) == schema.hash
    assert schema.hash.hex() == vectors["schema_hash"]


def test_crc_vectors(vectors):
    assert crc32c(b"123456789") == 0xE3069283  # CRC-32C catalogue check value
    for v in vectors["crc"]:
        assert crc32c(bytes.fromhex(v["data_hex"])) == v["crc32c"]


def test_frame_vectors(schema, vectors):
    assert len(vectors["frame"]) >= 10
    for v in vectors["frame"]:
        payload = bytes.fromhex(v["payload_hex"])
        assert encode_frame(v["id"], v["seq"], payload).hex() == v["frame_hex"], v["message"]
        frames, dropped = FrameDecoder().feed(bytes.fromhex(v["frame_hex"]))
        assert dropped == 0 and len(frames) == 1
        assert (frames[0].id, frames[0].seq, frames[0].payload) == (v["id"], v["seq"], payload)
        name, values = schema.decode(v["id"], payload)
        assert name == v["message"]
        assert schema.describe(name, values) == v["describe"]
        assert schema.encode(name, values) == payload


def test_layout_change_changes_hash_but_doc_does_not(schema):
    import copy

    from fuzzyctl.link.schema import Schema

    raw = copy.deepcopy(schema.raw)
    raw["message"][0]["doc"] = "another text"
    assert Schema(raw).hash == schema.hash
    raw["message"][0]["fields"][0]["type"] = "u16"
    assert Schema(raw).hash != schema.hash


def test_out_of_range_and_trailing_bytes_rejected(schema):
    with pytest.raises(CodecError):
        schema.encode("control", {"action": 9})
    with pytest.raises(CodecError):
        schema.decode(schema.by_name["control"].id, b"\x09")
    with pytest.raises(CodecError):
        schema.decode(schema.by_name["control"].id, b"\x01\x00")
    with pytest.raises(CodecError):
        schema.decode(0x7E, b"")


def test_decoder_resyncs_and_counts():
    good = encode_frame(0x0B, 5, b"\x01")
    bad = bytearray(encode_frame(0x0B, 6, b"\x02"))
    bad[3] ^= 0x40
    stream = b"\x13\x37\xff" + good + bytes(bad) + good + b"\x55" * 5000 + good
    d = FrameDecoder()
    frames = []
    for i in range(len(stream)):
        frames += d.feed(stream[i:i + 1])[0]
    assert [f.seq for f in frames] == [5, 5, 5]
    assert d.errors.crc + d.errors.cobs == 2 and d.errors.oversize == 1


# ---- property tests (hypothesis) ------------------------------------------------------------

hyp = pytest.importorskip("hypothesis")
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


@settings(max_examples=80, deadline=None)
@given(st.binary(max_size=3000))
def test_random_bytes_never_crash_the_decoder(data):
    s = load_schema()
    d = FrameDecoder()
    frames, _ = d.feed(data)
    for f in frames:
        try:
            s.decode(f.id, f.payload)
        except CodecError:
            pass


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 12), st.data())
def test_mutated_frames_are_dropped_or_identical(idx, data):
    """A mutation of a valid frame either fails the CRC/COBS check or (a mutation outside the
    frame bytes) leaves the decoded frame exactly as sent: never a different accepted frame."""
    s = load_schema()
    vec_payloads = [s.encode("telemetry", {"frame_id": 1, "stages": [{"name": "cost", "ms": 1.0}]}),
                    s.encode("config_chunk", {"offset": 3, "data": bytes(range(200))}),
                    s.encode("ack", {"status": 4, "text": "x"})]
    ids = [s.by_name[n].id for n in ("telemetry", "config_chunk", "ack")]
    k = idx % 3
    wire = bytearray(encode_frame(ids[k], 77, vec_payloads[k]))
    n_mut = data.draw(st.integers(1, 4))
    for _ in range(n_mut):
        pos = data.draw(st.integers(0, len(wire) - 1))
        op = data.draw(st.sampled_from(["flip", "insert", "delete", "dup"]))
        if op == "flip":
            wire[pos] ^= 1 << data.draw(st.integers(0, 7))
        elif op == "insert":
            wire.insert(pos, data.draw(st.integers(0, 255)))
        elif op == "delete" and len(wire) > 1:
            del wire[pos]
        else:
            wire.insert(pos, wire[pos])
    frames, _ = FrameDecoder().feed(bytes(wire))
    for f in frames:
        assert (f.id, f.seq, f.payload) == (ids[k], 77, vec_payloads[k])


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0, 1000, width=32), st.text(max_size=60),
       st.lists(st.tuples(st.integers(0, 65535), st.integers(0, 2), st.floats(0, 1000, width=32)), max_size=32))
def test_telemetry_round_trip(frame_id, fps, source, obstacles):
    s = load_schema()
    v = {"frame_id": frame_id, "fps": fps, "source": source[:60],
         "obstacles": [{"track_id": a, "cls": b, "distance_m": c, "lateral_m": 0.0, "width_m": 0.0} for a, b, c in obstacles]}
    if len(v["source"].encode()) > 255:
        return
    payload = s.encode("telemetry", v)
    name, back = s.decode(s.by_name["telemetry"].id, payload)
    assert back["frame_id"] == frame_id and back["source"] == v["source"]
    assert [o["track_id"] for o in back["obstacles"]] == [o[0] for o in obstacles]
    assert s.encode(name, back) == payload
