"""The stage dump format (docs/formats.md): fixed-point conversions, round trip, clear errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fuzzyctl import dump as dm
from fuzzyctl.errors import FatalError
from fuzzyctl.reference import match
from synthetic import shifted_pair, small_config


def test_q4_conversion_rounds_half_up_and_marks_invalid():
    d = np.array([0.0, 1.0, 2.5, 3.03125, 3.09375, np.nan, 63.96875])
    q = dm.disp_to_q4(d)
    assert q.dtype == np.int16
    np.testing.assert_array_equal(q, [0, 16, 40, 49, 50, -1, 1024])  # 3.03125*16 = 48.5 -> 49
    back = dm.q4_to_disp(q)
    assert np.isnan(back[5]) and back[2] == 2.5


def test_q16_conversion():
    q = dm.to_q16(np.array([0.0, 1.0, 0.5, 1 / 3]))
    assert q.dtype == np.int32
    np.testing.assert_array_equal(q, [0, 65536, 32768, 21845])
    assert dm.from_q16(q)[3] == pytest.approx(1 / 3, abs=1 / 65536)


@pytest.fixture(scope="module")
def ref_dump(tmp_path_factory, fis):
    left, right = shifted_pair(24, 40, 3, seed=8)
    cfg = small_config(cost__max_disparity=8)
    r = match(left, right, cfg, fis)
    out = tmp_path_factory.mktemp("run") / "dump"
    dm.write_dump(out, r, {"config_toml": cfg.to_toml(), "fis_name": fis.defn.name, "left": "l", "right": "r"})
    return out, r


def test_round_trip(ref_dump):
    path, r = ref_dump
    d = dm.read_dump(path.parent)  # RUN_DIR/dump is found from RUN_DIR
    assert d.path == path and (d.width, d.height) == (40, 24)
    np.testing.assert_array_equal(d.left, r.left)
    np.testing.assert_array_equal(d["labels_left"], r.labels_left)
    np.testing.assert_array_equal(d["seg_left"][:, dm.SEG_DISP], r.dec_left.disparity)
    np.testing.assert_allclose(dm.from_q16(d["seg_left"][:, dm.SEG_SCORE]), r.dec_left.score, atol=1 / 65536)
    np.testing.assert_array_equal(np.isnan(d.disp("disp_final")), np.isnan(r.disp_final))
    np.testing.assert_allclose(d.disp("disp_final"), r.disp_final, atol=1 / 32)
    np.testing.assert_array_equal(d["lr_mask"].astype(bool), r.lr_mask)
    for name, (dtype, _) in dm.ARRAYS.items():
        assert d[name].dtype == dtype
    assert set(d.meta["timings_ms"]) == {"gradient", "segmentation", "cost", "wta", "lrcheck", "esr", "densify"}
    assert d.meta["lr_check"]["retry_recovered"] == r.retry_recovered  # as the firmware's dump (docs/formats.md)


def _copy(src, dst):
    import shutil

    shutil.copytree(src, dst)
    return dst


def test_missing_dump(tmp_path):
    with pytest.raises(FatalError, match="does not exist"):
        dm.read_dump(tmp_path / "nothing")
    with pytest.raises(FatalError, match=r"no dump in .*neither .*meta.json"):
        dm.read_dump(tmp_path)


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: (d / "meta.json").write_text("{not json"), r"meta.json is not valid JSON"),
        (lambda d: (d / "meta.json").write_text(json.dumps({"format": "x", "version": 1})), r"meta.json: format is 'x'"),
        (lambda d: _edit_meta(d, version=7), r"dump version 7 is not supported"),
        (lambda d: _edit_meta(d, width="wide"), r"'width' must be a positive integer"),
        (lambda d: (d / "disp_final.npy").unlink(), r"dump file .*disp_final.npy is missing"),
        (lambda d: (d / "lr_mask.npy").write_bytes(b"garbage"), r"dump file .*lr_mask.npy is not a readable .npy"),
        (lambda d: np.save(d / "disp_lr.npy", np.zeros((24, 40), np.int32)), r"disp_lr.npy has dtype int32, expected int16"),
        (lambda d: np.save(d / "disp_lr.npy", np.zeros((24, 41), np.int16)), r"disp_lr.npy has shape \(24, 41\), expected \(24, 40\)"),
        (lambda d: np.save(d / "seg_left.npy", np.zeros((3, 4), np.int32)), r"seg_left.npy has 3 rows but labels_left.npy has"),
        (lambda d: (d / "left.png").unlink(), r"dump file .*left.png is missing"),
    ],
)
def test_malformed_dump_names_the_file(ref_dump, tmp_path, mutate, message):
    d = _copy(ref_dump[0], tmp_path / "dump")
    mutate(d)
    with pytest.raises(FatalError, match=message):
        dm.read_dump(d)


def _edit_meta(d, **changes):
    meta = json.loads((d / "meta.json").read_text())
    meta.update(changes)
    (d / "meta.json").write_text(json.dumps(meta))


def test_read_labels(ref_dump, tmp_path):
    ll, lr = dm.read_labels(ref_dump[0])
    assert ll.dtype == np.int32 and ll.shape == (24, 40)
    d = _copy(ref_dump[0], tmp_path / "dump")
    np.save(d / "labels_right.npy", np.zeros(5, np.float32))
    with pytest.raises(FatalError, match=r"labels_right.npy: expected an integer \(H, W\) label image"):
        dm.read_labels(d)
