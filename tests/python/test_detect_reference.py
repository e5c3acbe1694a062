"""Float64 detection reference (fuzzyctl.reference.detect) and `fuzzyctl compare` on detect dumps:
the reference's stages against direct computations, and the firmware's detect dump against the
reference (oracle and matcher disparities), including a corrupted dump that must fail."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import detect_synth
from fuzzyctl import cli
from fuzzyctl.config import load_config
from fuzzyctl.detect_compare import compare_detect
from fuzzyctl.reference import detect as refdet


def params(**overrides):
    p = refdet.params_from_config(load_config())
    p.values.update(overrides)
    return p


def test_hsv_float_equations():
    rgb = np.array([[[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 0, 10], [100, 150, 230], [0, 0, 0], [200, 200, 200]]],
                   np.uint8)
    h, s, v = refdet.rgb_to_hsv(rgb)
    assert h[0, :4] == pytest.approx([0, 120, 240, 360 - 60 * 10 / 255])
    assert h[0, 4] == pytest.approx(60 * ((100 - 150) / 130 + 4))  # Cmax = B
    assert s[0, 4] == pytest.approx(130 / 230 * 100) and v[0, 4] == pytest.approx(230 / 255 * 100)
    assert (s[0, 5], v[0, 5], h[0, 6], s[0, 6]) == (0, 0, 0, 0)


def test_closing_keeps_border_and_fills_holes():
    m = np.ones((20, 30), np.uint8)
    m[8:10, 5:25] = 0  # 2-row gap: filled by r = 2
    m[0, :] = 0        # the top row is not "eroded in" from outside
    c = refdet.close_mask(m, 2)
    assert c[8:10, 5:25].all()
    assert c[1:, :].all()


def test_kmeans_merge_and_order():
    vals = np.concatenate([np.full(100, 10.0) + np.linspace(-0.2, 0.2, 100), np.full(50, 4.0)])
    centres, lab = refdet.kmeans_1d(vals, 6, 30, merge_px=1.0)
    assert len(centres) == 2 and centres[0] == pytest.approx(10.0, abs=0.05) and centres[1] == pytest.approx(4.0)
    assert (lab[:100] == 0).all() and (lab[100:] == 1).all()
    centres6, _ = refdet.kmeans_1d(vals, 6, 30, merge_px=0.0)
    assert len(centres6) > 2 and centres6 == sorted(centres6, reverse=True)


def test_reference_finds_scene_obstacles():
    left, _, disp, road, _, _, gt = detect_synth.render(detect_synth.SCENES[0][1], "clear", seed=1)
    d = np.where(disp > 0, disp, np.nan)
    calib = {"focal_px": detect_synth.F, "baseline_m": detect_synth.B, "cx": detect_synth.CX, "cy": detect_synth.CY}
    r = refdet.detect(d, left[..., ::-1], calib, params())
    assert r.road_found and r.road_a == pytest.approx(0.2, abs=0.02)
    assert [o.distance_m for o in r.obstacles] == pytest.approx([g["distance_m"] for g in gt], rel=0.05)
    assert (r.road_mask.astype(bool) & road).sum() / (r.road_mask.astype(bool) | road).sum() > 0.9
    mono = refdet.detect(d, None, calib, params())
    assert mono.sky_skipped and not mono.sky_mask.any() and len(mono.obstacles) == 2


# ---- firmware dump vs reference --------------------------------------------------------------

@pytest.fixture(scope="module")
def dumps(firmware_bin, tmp_path_factory) -> dict[str, Path]:
    root = detect_synth.write_dataset(tmp_path_factory.mktemp("sim"))
    tr = root / "training"
    out = {}
    for mode in ("oracle", "matcher"):
        d = tmp_path_factory.mktemp(mode)
        src = ["--disparity", tr / "disp_occ_0/000000_10.png"] if mode == "oracle" else \
              ["--right", tr / "image_3/000000_10.png", "--max-disparity", "32"]
        p = subprocess.run([str(firmware_bin), "detect", "--left", str(tr / "image_2/000000_10.png"), *map(str, src),
                            "--calib", str(tr / "sim_gt/000000_10.json"), "--out", str(d), "--dump"],
                           capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stderr
        out[mode] = d
    return out


@pytest.mark.firmware
@pytest.mark.parametrize("mode", ["oracle", "matcher"])
def test_firmware_dump_matches_reference(dumps, mode):
    c = compare_detect(dumps[mode])
    assert not c.failures(), [(m.name, m.value) for m, _ in c.failures()]
    vals = {m.name: m.value for m in c.metrics}
    assert vals["obstacle_count_abs_diff"] == 0 and vals["obstacle_box_iou_min"] >= 0.8


@pytest.mark.firmware
def test_compare_catches_a_corrupted_dump(dumps, tmp_path):
    bad = tmp_path / "bad"
    shutil.copytree(dumps["oracle"], bad)
    road = np.load(bad / "dump/road_mask.npy")
    road[road.shape[0] // 2:, :] ^= 1  # the lower half's road decisions inverted
    np.save(bad / "dump/road_mask.npy", road)
    meta = json.loads((bad / "dump/detect_meta.json").read_text())
    meta["obstacles"][0]["distance_m"] *= 1.2
    (bad / "dump/detect_meta.json").write_text(json.dumps(meta))
    failing = {m.name for m, _ in compare_detect(bad).failures()}
    assert {"road_mask_agreement_pct", "obstacle_distance_rel_diff_max"} <= failing
    assert cli.main(["compare", str(bad)]) != 0
    assert cli.main(["compare", str(dumps["oracle"])]) == 0


@pytest.mark.firmware
def test_reference_detect_command(dumps, tmp_path):
    assert cli.main(["reference", "detect", "--dump", str(dumps["oracle"]), "--out", str(tmp_path / "ref")]) == 0
    doc = json.loads((tmp_path / "ref/obstacles.json").read_text())
    fw = json.loads((dumps["oracle"] / "obstacles.json").read_text())
    assert len(doc["obstacles"]) == len(fw["obstacles"]) == 2
    assert np.load(tmp_path / "ref/road_mask.npy").shape == np.load(dumps["oracle"] / "dump/road_mask.npy").shape
    assert cli.main(["reference", "detect", "--dump", str(tmp_path), "--out", str(tmp_path / "x")]) == 2


def test_relative_step_separates_far_neighbours():
    # Two touching surfaces at 6.7 px and 5.7 px: the absolute 1-px step joins them, a 3 % relative
    # step (0.2 px at 6.7 px, floor 0.25 px) keeps them apart; a 0.25-px step still joins.
    mask = np.ones((6, 20), np.uint8)
    disp = np.where(np.arange(20)[None, :] < 10, 6.6875, 5.6875) * np.ones((6, 1))
    assert refdet.components(mask, disp, 1.0)[1] == 1
    lab, n = refdet.components(mask, disp, 1.0, 0.03, 0.25)
    assert n == 2 and lab[3, 9] != lab[3, 10]
    disp[:, 10:] = 6.4375
    assert refdet.components(mask, disp, 1.0, 0.03, 0.25)[1] == 1


def test_bimodal_split_separates_ramp_joined_depths():
    # Two surfaces at 20 px and 14 px joined by a 2-column ramp: one component, split in two; a
    # slanted surface over the same range stays whole (flat histogram, valley ~25 %).
    d = np.full((60, 120), np.nan)
    mask = np.zeros((60, 120), np.uint8)
    mask[10:50, 10:110] = 1
    xs = np.arange(120)
    row = np.where(xs < 59, 20.0, np.where(xs == 59, 18.1, np.where(xs == 60, 16.25, 14.0)))
    d[10:50] = row
    comp, n = refdet.components(mask, d, 4.0)
    assert n == 1
    s, ns = refdet.split_bimodal(comp, n, d, 100, 0.12, 0.1, 2)
    assert ns == 2 and s[20, 20] != s[20, 100] and s[20, 20] == s[49, 58]
    assert refdet.split_bimodal(comp, n, d, 100, 0.0, 0.1, 2)[1] == 1  # off
    d[10:50, 10:110] = 20.0 - (np.arange(100) * 6.0 / 99)
    comp, n = refdet.components(mask, d, 4.0)
    assert refdet.split_bimodal(comp, n, d, 100, 0.12, 0.1, 2)[1] == 1


def _boxes(shape, boxes, dtype=np.int64):
    """(component labels, disparity) with each (x0, x1, y0, y1, label, disparity px) box filled (inclusive)."""
    comp = np.zeros(shape, dtype)
    d = np.full(shape, np.nan)
    for (x0, x1, y0, y1, lab, disp) in boxes:
        comp[y0:y1 + 1, x0:x1 + 1] = lab
        d[y0:y1 + 1, x0:x1 + 1] = disp
    return comp, d


def test_occluded_obstacle_merges_across_nearer_one():
    comp, d = _boxes((80, 200), [(10, 39, 20, 59, 1, 20.0), (40, 89, 5, 75, 2, 40.0), (90, 119, 20, 59, 3, 20.1)], np.int32)
    roots = refdet.merge_fragments(comp, d, 3, 8, 0.1)
    assert len(set(roots[1:].tolist())) == 3
    r = refdet.merge_occluded(comp, d, 3, roots, 8, 0.1, 200, 10)
    assert r[1] == r[3] != r[2]
    assert len(set(refdet.merge_occluded(comp, d, 3, roots, 8, 0.1, 40, 10)[1:].tolist())) == 3  # gap 50 > 40
    comp2 = comp.copy()
    comp2[20:30, 90:120] = 0  # right piece starts 10 rows lower: another obstacle
    assert len(set(refdet.merge_occluded(comp2, d, 3, roots, 8, 0.1, 200, 10)[1:].tolist())) == 3


def test_vertical_gap_joins_a_post_cut_in_height():
    # As tests/cpp/core/test_detect_scene.cpp VerticalGapJoinsAPostCutInHeight: a post in two
    # stacked pieces 12 rows apart and two side-by-side pieces 12 columns apart, all at 20 px.
    comp = np.zeros((70, 100), np.int64)
    d = np.full((70, 100), np.nan)
    for (x0, x1, y0, y1, lab) in [(10, 19, 5, 24, 1), (10, 19, 37, 59, 2), (50, 59, 20, 59, 3), (72, 81, 20, 59, 4)]:
        comp[y0:y1 + 1, x0:x1 + 1] = lab
        d[y0:y1 + 1, x0:x1 + 1] = 20.0
    assert len(set(refdet.merge_fragments(comp, d, 4, 8, 0.1, gap_vertical=8)[1:].tolist())) == 4
    r = refdet.merge_fragments(comp, d, 4, 8, 0.1, gap_vertical=16)
    assert r[1] == r[2] and len({r[1], r[3], r[4]}) == 3


def test_small_bridge_joins_one_side_only():
    # As tests/cpp/core/test_detect_linkage.cpp SmallBridgeNoLongerJoinsObstaclesSideBySide and
    # SmallBridgeStillJoinsAPieceInTheSameColumns (session 10): A at 20 px, B beside it at 17 px (15 % farther),
    # a 66-px bridge C at 18.5 px between them; then D at 17 px below A, in A's columns, with a small C between.
    comp, d = _boxes((100, 100), [(10, 39, 10, 49, 1, 20.0), (42, 47, 20, 30, 2, 18.5), (50, 79, 10, 39, 3, 17.0)])
    assert len(set(refdet.merge_fragments(comp, d, 3, 8, 0.1)[1:].tolist())) == 1  # single linkage: one chain
    r = refdet.merge_fragments(comp, d, 3, 8, 0.1, bridge_px=500, bridge_overlap=0.5)
    assert r[1] == r[2] != r[3]
    comp, d = _boxes((100, 100), [(10, 39, 10, 49, 1, 20.0), (20, 25, 51, 56, 2, 18.5), (12, 37, 60, 79, 3, 17.0)])
    r = refdet.merge_fragments(comp, d, 3, 8, 0.1, bridge_px=500, bridge_overlap=0.5)
    assert r[1] == r[2] == r[3]
    r = refdet.merge_fragments(comp, d, 3, 8, 0.1, bridge_px=500, bridge_overlap=1.0)
    assert r[1] == r[2] != r[3]


def test_contained_groups_join_or_drop():
    # As tests/cpp/core/test_detect_scene.cpp ContainedGroupsJoinOrDrop: an obstacle at 20 px with a
    # 15 %-nearer piece (200 px), a nearer 100-px blob and a farther 100-px blob inside its box.
    comp = np.zeros((100, 120), np.int64)
    d = np.full((100, 120), np.nan)
    for (x0, x1, y0, y1, lab, v) in [(20, 79, 20, 79, 1, 20.0), (30, 39, 30, 49, 2, 23.0),
                                     (50, 59, 30, 39, 3, 40.0), (50, 59, 60, 69, 4, 12.0)]:
        comp[y0:y1 + 1, x0:x1 + 1] = lab
        d[y0:y1 + 1, x0:x1 + 1] = v
    roots = np.arange(5)
    r = refdet.resolve_contained(comp, d, 4, roots, 0.8, 0.2, 150, False, 10)
    assert r[1:].tolist() == [1, 1, 0, 0]  # piece joined, both blobs dropped
    assert refdet.resolve_contained(comp, d, 4, roots, 0.8, 0.2, 150, True, 10)[1:].tolist() == [1, 1, 0, 4]
    assert refdet.resolve_contained(comp, d, 4, roots, 0.8, 0.2, 100, False, 10)[1:].tolist() == [1, 1, 3, 4]
    assert refdet.resolve_contained(comp, d, 4, roots, 0.8, 0.1, 150, False, 10)[1:].tolist() == [1, 2, 0, 0]
    assert refdet.resolve_contained(comp, d, 4, roots, 0.0, 0.2, 150, False, 10)[1:].tolist() == [1, 2, 3, 4]
    comp2, d2 = comp.copy(), d.copy()
    comp2[30:50, 30:40], d2[30:50, 30:40] = 1, 20.0
    comp2[10:30, 30:40], d2[10:30, 30:40] = 2, 23.0  # half above the obstacle's box: not contained
    assert refdet.resolve_contained(comp2, d2, 4, roots, 0.8, 0.2, 150, False, 10)[1:].tolist() == [1, 2, 0, 0]
    # A blob in the obstacle's corner (obstacle pixels only left of and above it) is not surrounded.
    comp3, d3 = comp.copy(), d.copy()
    comp3[70:80, 70:80], d3[70:80, 70:80] = 3, 40.0
    comp3[30:40, 50:60], d3[30:40, 50:60] = 1, 20.0
    assert refdet.resolve_contained(comp3, d3, 4, roots, 0.8, 0.2, 150, False, 10)[1:].tolist() == [1, 1, 3, 0]
    assert refdet.resolve_contained(comp3, d3, 4, roots, 0.8, 0.2, 150, False, 10, "off")[1:].tolist() == [1, 1, 0, 0]


def test_edge_continuity_joins_a_slanted_surface():
    # A surface slanting from d = 30 px (left) to 24 px (right), cut into two pieces 2 px apart (as where
    # two k-means clusters meet): medians 28.5 / 25.5 px (11 %) but the facing edges agree. A flat obstacle
    # at 21 px beside the near end of another surface (edges 30 vs 21) stays apart.
    comp = np.zeros((60, 200), np.int64)
    d = np.full((60, 200), np.nan)
    ramp = np.linspace(30.0, 24.0, 62)
    comp[10:50, 10:40], comp[10:50, 42:72] = 1, 2
    d[10:50, 10:72] = ramp[None, :]
    d[10:50, 40:42] = np.nan
    comp[10:50, 100:130], d[10:50, 100:130] = 3, 30.0
    comp[10:50, 132:160], d[10:50, 132:160] = 4, 21.0
    roots = np.arange(5)
    r = refdet.merge_edges(comp, d, 4, roots, 8, 0.05, 4)
    assert r[1:].tolist() == [1, 1, 3, 4]
    assert refdet.merge_edges(comp, d, 4, roots, 8, 0.0, 4)[1:].tolist() == [1, 2, 3, 4]  # off
    assert refdet.merge_edges(comp, d, 4, roots, 1, 0.05, 4)[1:].tolist() == [1, 2, 3, 4]  # gap 2 > 1
    assert refdet.merge_edges(comp, d, 4, roots, 8, 0.05, 30)[1:].tolist() == [1, 2, 3, 4]  # whole pieces: 11 %


def test_below_road_drops_and_renumbers():
    # As tests/cpp/core/test_detect_below_road.cpp: road line d = 0.2 (v - 50).
    h, w = 120, 60
    ol = np.zeros((h, w), np.int32)
    obs = []
    for i, (x0, d, y0, y1) in enumerate([(0, 10.0, 80, 99), (15, 5.0, 85, 95), (30, 5.0, 60, 76)]):
        ol[y0:y1 + 1, x0:x0 + 10] = i + 1
        obs.append(refdet.Obstacle(i, (x0, y0, x0 + 9, y1), (y1 - y0 + 1) * 10, d, 1.0, 0.0, "near"))
    p = params(below_road_drop_share=0.5)
    kept = refdet.drop_below_road(obs, ol, 0.2, -10.0, 51, p)
    assert [o.box[0] for o in kept] == [0, 30] and [o.id for o in kept] == [0, 1]
    assert ol[70, 35] == 2 and ol[90, 20] == 0 and ol[90, 5] == 1
    assert len(refdet.drop_below_road(obs[:1], ol, 0.2, -10.0, 51, params(below_road_drop_share=0.0))) == 1


def test_road_slope_prior_range():
    # As tests/cpp/core/test_detect_slope_prior.cpp: a0 = B cos(pitch) / h = 0.1 / 0.5.
    calib = {"baseline_m": 0.1, "height_m": 0.5, "pitch_deg": 0.0}
    assert refdet.road_slope_range(params(road_slope_prior_rel=0.5), calib) == pytest.approx((0.2 / 1.5, 0.3))
    assert refdet.road_slope_range(params(road_slope_prior_rel=0.0), calib) == pytest.approx((0.02, 2.0))
    assert refdet.road_slope_range(params(road_slope_prior_rel=0.5), {**calib, "height_m": 0.0}) == pytest.approx((0.02, 2.0))
    lo, hi = refdet.road_slope_range(params(road_slope_prior_rel=0.1, road_slope_max=0.1), calib)
    assert lo > hi  # no line can be accepted


def test_inside_nearer_drops_and_renumbers():
    # As tests/cpp/core/test_detect_linkage.cpp DetectInsideNearer: H at 20 px (rows 10..49, columns 10..49)
    # with a farther blob F at 15 px in a hole reaching its bottom edge, G at 15 px beside H.
    ol = np.zeros((60, 100), np.int32)
    ol[10:50, 10:50] = 1
    ol[35:50, 20:36] = 2
    ol[15:46, 60:80] = 3
    obs = [refdet.Obstacle(0, (10, 10, 49, 49), int((ol == 1).sum()), 20.0, 1.0, 0.0, "near"),
           refdet.Obstacle(1, (20, 35, 35, 49), 240, 15.0, 1.0, 0.0, "near"),
           refdet.Obstacle(2, (60, 15, 79, 45), 620, 15.0, 1.0, 0.0, "near")]
    p = params(inside_drop_min_share=0.85, inside_drop_min_ring=0.25, inside_drop_ring_px=6)
    assert len(refdet.drop_seen_through(list(obs), ol.copy(), params(seen_through_drop_share=0.5))) == 3
    assert len(refdet.drop_inside_nearer(list(obs), ol.copy(), params(inside_drop_min_share=0.0))) == 3
    kept = refdet.drop_inside_nearer(list(obs), ol, p)
    assert [o.box[0] for o in kept] == [10, 60] and [o.id for o in kept] == [0, 1]
    assert ol[40, 25] == 0 and ol[30, 70] == 2 and ol[12, 12] == 1
    # A real obstacle seen in the gap of a box that joined two blocks: the band around it holds none of them.
    ol2 = np.zeros((60, 100), np.int32)
    ol2[10:50, 10:20] = 1
    ol2[10:50, 60:70] = 1
    ol2[15:46, 30:50] = 2
    obs2 = [refdet.Obstacle(0, (10, 10, 69, 49), 800, 20.0, 1.0, 0.0, "near"),
            refdet.Obstacle(1, (30, 15, 49, 45), 620, 15.0, 1.0, 0.0, "near")]
    assert len(refdet.drop_inside_nearer(list(obs2), ol2.copy(), p)) == 2
    assert len(refdet.drop_inside_nearer(list(obs2), ol2.copy(), params(inside_drop_min_share=0.85,
                                                                        inside_drop_min_ring=0.0))) == 1


def test_gap_to_the_foot_closed_unless_hidden():
    # As tests/cpp/core/test_detect_extent.cpp GapToTheFoot...: road line d = 0.2 (v - 50), F at 10 px measured
    # in rows 20..60 (foot row 99), N at 15 px hiding the last rows of the gap.
    def run(n_rows, n_disp, **kw):
        ol = np.zeros((120, 40), np.int32)
        ol[20:61, 10:31] = 2
        ol[100 - n_rows:100, 5:36] = 1
        obs = [refdet.Obstacle(0, (5, 100 - n_rows, 35, 99), 31 * n_rows, n_disp, 1.0, 0.0, "near"),
               refdet.Obstacle(1, (10, 20, 30, 60), 21 * 41, 10.0, 1.0, 0.0, "near")]
        refdet.extend_over_gap(obs, ol, 0.2, -10.0, 51, 120, params(**{"foot_gap_extend": True,
                                                                       "foot_gap_max_occluded": 0.3, **kw}))
        return obs[0].box[3], obs[1].box[3]
    assert run(10, 15.0) == (119, 99)     # 26 % of the gap hidden: F reaches its foot; N its (below the image)
    assert run(20, 15.0)[1] == 60         # 51 % hidden: F's lower part is behind N
    assert run(20, 10.625)[1] == 99       # N within merge_max_rel_disparity: not an occluder
    assert run(10, 15.0, foot_gap_extend=False) == (99, 60)


def test_split_necks_cuts_a_strip_at_the_feet():
    # The scene of the C++ test DetectScene.TwoObstaclesJoinedAtTheirFeetAreCutAtTheNeck.
    comp = np.zeros((70, 120), np.int32)
    comp[10:60, 10:40] = comp[10:60, 70:100] = comp[54:60, 40:70] = 1
    s, n = refdet.split_necks(comp, 1, 12, 0.3, 100)
    assert n == 2 and s[30, 20] == 1 and s[30, 80] == 2 and s[57, 55] == 0 and s[57, 39] == 1
    assert np.array_equal(refdet.split_necks(comp, 1, 12, 0.3, 100, 0.2)[0], s)
    top = comp.copy()
    top[10:60, 40:70] = 0
    top[10:16, 40:70] = 1
    assert refdet.split_necks(top, 1, 12, 0.3, 100, 0.2)[1] == 1
    assert refdet.split_necks(top, 1, 12, 0.3, 100, 0.0)[1] == 2
    for args in [(31, 0.3, 100), (12, 0.3, 1501), (12, 0.1, 100), (0, 0.3, 100)]:
        assert np.array_equal(refdet.split_necks(comp, 1, *args)[0], comp), args
    tail = comp.copy()
    tail[10:54, 70:100] = 0
    tail[54:60, 70:100] = 1
    assert refdet.split_necks(tail, 1, 12, 0.3, 100)[1] == 1


def _seam_scene(paint):
    # The scenes of the C++ tests DetectScene.TwoTouchingObstaclesOfDifferentColourAreCutAtTheSeam and
    # DetectScene.ColourBlobsOfOneSurfaceAreNotASeam: one label over columns 10-69, rows 10-59.
    lab = np.zeros((70, 120), np.int32)
    rgb = np.zeros((70, 120, 3), np.uint8)
    lab[10:60, 10:70] = 1
    for y in range(10, 60):
        for x in range(10, 70):
            rgb[y, x] = paint(x, y)
    return lab, rgb


RED, BLUE = (200, 40, 40), (40, 40, 200)


def test_split_seams_cuts_two_touching_obstacles_of_different_colour():
    lab, rgb = _seam_scene(lambda x, y: RED if x < 40 else BLUE)
    s, n = refdet.split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 2, 0.7)
    assert n == 2 and s[30, 39] == 1 and s[30, 40] == 2 and s[59, 10] == 1 and s[10, 69] == 2
    for step, width, px in [(0.0, 14, 300), (0.6, 14, 300), (0.08, 31, 300), (0.08, 14, 1501)]:
        s2, n2 = refdet.split_seams(lab, 1, rgb, step, 8, width, px, 2, 0.7)
        assert n2 == 1 and np.array_equal(s2, lab), step
    assert refdet.split_seams(lab, 1, None, 0.08, 8, 14, 300, 2, 0.7)[1] == 1
    lab, rgb = _seam_scene(lambda x, y: RED if x < 24 else BLUE)
    s, n = refdet.split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 2, 0.7)
    assert n == 2 and s[30, 23] == 1
    s, n = refdet.split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 2, 0.7, 0.25)
    assert n == 1 and s[30, 23] == 0 and s[30, 24] == 1


def test_split_seams_leaves_colour_blobs_of_one_surface_whole():
    lab, rgb = _seam_scene(lambda x, y: RED if x < (50 if y < 35 else 30) else BLUE)
    s, n = refdet.split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 2, 0.7)
    assert n == 1 and np.array_equal(s, lab)
    s, n = refdet.split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 2, 0.0)
    assert n == 3 and s[12, 29] == 1 and s[12, 30] == 2 and s[12, 49] == 2 and s[12, 50] == 3
    assert refdet.split_seams(lab, 1, rgb, 0.08, 8, 14, 300, 1, 0.0)[0][12, 50] == 2


TWO_BOXES = """seed = 7
type = "clear"
[camera]
width = 320
height = 180
focal_px = 210.0
baseline_m = 0.12
height_m = 0.40
pitch_deg = 5.0
[sky]
kind = "clear"
[ground]
texture = "asphalt"
[[obstacles]]
shape = "box"
x_m = 4.0
y_m = 0.35
length_m = 0.5
width_m = 0.7
height_m = 0.9
texture = "noise"
color = [200, 60, 50]
[[obstacles]]
shape = "box"
x_m = 4.0
y_m = -0.35
length_m = 0.5
width_m = 0.7
height_m = 0.9
texture = "noise"
color = [50, 70, 200]
"""


@pytest.mark.firmware
def test_seams_split_touching_boxes_in_firmware_and_reference(firmware_bin, tmp_path):
    # Two boxes side by side at one depth (a red and a blue one, touching): one obstacle with the ground-truth
    # disparity and the defaults (seams off); two with [detect] seam_min_step = 0.08, in the firmware and in
    # the float reference alike (`fuzzyctl compare` on the dump).
    (tmp_path / "scene.toml").write_text(TWO_BOXES)
    r = subprocess.run([str(firmware_bin), "sim", "render", str(tmp_path / "scene.toml"), "--out", str(tmp_path / "r")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    text = (Path(__file__).resolve().parents[2] / "common/config/default.toml").read_text()
    assert re.search(r"^seam_min_step = ", text, re.M)
    for name, step in (("off", "0.0"), ("on", "0.08")):
        (tmp_path / f"{name}.toml").write_text(re.sub(r"^seam_min_step = .*$", f"seam_min_step = {step}", text, flags=re.M))
    counts = {}
    for name, cfg in (("off", tmp_path / "off.toml"), ("on", tmp_path / "on.toml")):
        out = tmp_path / name
        r = subprocess.run([str(firmware_bin), "detect", "--left", str(tmp_path / "r/left.png"), "--disparity",
                            str(tmp_path / "r/disp_gt.png"), "--calib", str(tmp_path / "r/calib_cam_to_cam.txt"),
                            "--config", str(cfg), "--out", str(out), "--dump"], capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr
        obs = json.loads((out / "obstacles.json").read_text())["obstacles"]
        counts[name] = len(obs)
        c = compare_detect(out)
        assert not c.failures(), [(m.name, m.value) for m, _ in c.failures()]
    assert counts == {"off": 1, "on": 2}


def test_side_face_of_a_box_joins_its_front_face():
    # The cases of the C++ test DetectScene.TheSideFaceOfABoxJoinsItsFrontFace.
    def run(fx0, fx1, f_px, **over):
        ol = np.zeros((70, 80), np.int32)
        ol[10:60, 10:50] = 1
        strip = ol[12:59, fx0:fx1 + 1]
        strip[strip == 0] = 2
        obs = [refdet.Obstacle(0, (10, 10, 49, 59), 2000, 20.0, 2.0, 0.0, "mid"),
               refdet.Obstacle(1, (fx0, 12, fx1, 58), 300, f_px, 2.5, 0.0, "mid")]
        p = params(**{"side_face_max_rel": 0.35, "side_face_max_width": 0.2, "side_face_min_rows": 0.8,
                      "side_face_max_gap_px": 2, **over})
        return refdet.merge_side_faces(obs, ol, p), ol
    out, ol = run(49, 54, 16.0)
    assert len(out) == 1 and out[0].box == (10, 10, 54, 59) and out[0].pixel_count == 2300
    assert out[0].disparity_px == 20.0 and ol[30, 52] == 1
    assert len(run(51, 56, 16.0)[0]) == 1
    for args in [(49, 54, 14.0), (49, 54, 22.0), (49, 57, 16.0), (53, 58, 16.0)]:
        assert len(run(*args)[0]) == 2, args
    assert len(run(49, 54, 16.0, side_face_max_rel=0.0)[0]) == 2
