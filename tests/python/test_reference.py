"""The float64 desktop reference: each stage against a plain independent computation, and the
whole pipeline on synthetic pairs with known disparity."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzyctl.reference import cost, esr, image, lrcheck, match, segmentation, wta
from synthetic import grid_labels, shifted_pair, small_config, texture, two_plane_pair

# ---- eq. (5) ---------------------------------------------------------------------------------


def _sobel_scalar(img: np.ndarray) -> np.ndarray:
    """The firmware's integer loop (gradient.cpp), transcribed."""
    h, w = img.shape
    I = img.astype(np.int64)
    out = np.zeros((h, w))
    for y in range(h):
        up, mid, dn = I[max(y - 1, 0)], I[y], I[min(y + 1, h - 1)]
        for x in range(w):
            xl, xr = max(x - 1, 0), min(x + 1, w - 1)
            gx = (up[xr] - up[xl]) + 2 * (mid[xr] - mid[xl]) + (dn[xr] - dn[xl])
            gy = (dn[xl] - up[xl]) + 2 * (dn[x] - up[x]) + (dn[xr] - up[xr])
            v = gx * gx + gy * gy
            r = math.isqrt(v)
            out[y, x] = r + 1 if v - r * r > r else r
    return out


def test_gradient_matches_scalar_sobel_on_odd_size():
    img = texture(17, 31, seed=5, blur=0.6)
    np.testing.assert_array_equal(image.gradient_magnitude(img), _sobel_scalar(img))


def test_gradient_gain_compensation_undoes_a_gain_and_respects_the_dead_band():
    img = np.random.default_rng(3).integers(0, 256, (23, 37)).astype(np.uint8)
    g = image.gradient_magnitude(img)
    dim = np.floor(g * 0.6)
    back, f = image.compensate_gradient_gain(g, dim, 0.2)
    assert f == pytest.approx(g.sum() / dim.sum())
    assert np.abs(back - g).max() <= 2
    same, f1 = image.compensate_gradient_gain(g, dim, 0.7)  # 0.6x is a 67 % difference
    assert f1 == 1.0 and same is dim
    flat, f0 = image.compensate_gradient_gain(g, np.zeros_like(g), 0.0)
    assert f0 == 1.0 and not flat.any()


def test_grey_quantile_shift_matches_sorting_and_detects_a_gain():
    rng = np.random.default_rng(4)
    for h, w in [(9, 17), (31, 53), (7, 1)]:
        a = rng.integers(0, 256, (h, w)).astype(np.uint8)
        b = rng.integers(40, 200, (h, w)).astype(np.uint8)

        def q(img, p):
            v = np.sort(img.ravel())
            return int(v[-(-p * v.size // 100) - 1])

        want = sum(abs(q(a, p) - q(b, p)) for p in range(5, 100, 5)) / 19.0
        assert image.grey_quantile_shift(a, b) == want
        assert image.grey_quantile_shift(a, a) == 0.0
    img = texture(40, 64, seed=2, blur=0.8)
    dim = np.floor(img * 0.6 + 0.5).astype(np.uint8)
    assert image.grey_quantile_shift(img, dim) > 13.0  # the default gradient_gain_grey_shift


# ---- noise equalisation (docs/algorithm.md 2c) ---------------------------------------------------


def _smooth_scene(h: int, w: int, sigma: float, seed: int) -> np.ndarray:
    """A ramp with a bright disc (edges, no fine texture) plus white noise of std sigma."""
    y, x = np.mgrid[0:h, 0:w]
    v = 60.0 + 100.0 * x / w + 20.0 * y / h + 50.0 * (((x - w // 2) ** 2 + (y - h // 2) ** 2) < (h // 3) ** 2)
    v = v + np.random.default_rng(seed).normal(0.0, sigma, v.shape) if sigma > 0 else v
    return np.clip(np.rint(v), 0, 255).astype(np.uint8)


def test_binomial_smooth_is_the_3x3_binomial_with_replicated_border():
    img = np.random.default_rng(8).integers(0, 256, (13, 29)).astype(np.uint8)
    p = np.pad(img.astype(np.int64), 1, mode="edge")
    k = np.outer([1, 2, 1], [1, 2, 1])
    want = np.zeros(img.shape, dtype=np.int64)
    for j in range(3):
        for i in range(3):
            want += k[j, i] * p[j : j + img.shape[0], i : i + img.shape[1]]
    np.testing.assert_array_equal(image.binomial_smooth(img), (want + 8) // 16)


def test_noise_estimate_and_excess():
    assert image.estimate_noise_sigma(_smooth_scene(121, 201, 0.0, 1)) < 0.7
    for sigma in (2.0, 4.0, 8.0):
        assert image.estimate_noise_sigma(_smooth_scene(121, 201, sigma, 7)) == pytest.approx(sigma, rel=0.15)
    assert image.noise_excess(3.0, 5.0, 100, 100) == pytest.approx(4.0)
    assert image.noise_excess(4.0, 2.4, 200, 120) == pytest.approx(0.0)  # a gain, not noise
    ramp = np.arange(200, dtype=np.uint8)[None, :]
    assert image.grey_spread(ramp) == 180


def test_noise_equalise_smooths_only_unequal_pairs():
    clean = _smooth_scene(64, 96, 0.0, 2)
    noisy = _smooth_scene(64, 96, 6.0, 3)
    l, r, gl, gr, done = image.noise_equalise(clean, clean, 2.3, 1, 2)
    assert not done and l is clean and gl is clean
    l, r, gl, gr, done = image.noise_equalise(clean, noisy, 2.3, 1, 2)
    assert done
    np.testing.assert_array_equal(l, image.binomial_smooth(clean))
    np.testing.assert_array_equal(gr, image.binomial_smooth(image.binomial_smooth(noisy)))
    assert not image.noise_equalise(clean, noisy, 0.0, 1, 2)[4]  # off


def test_gradient_extremes():
    img = np.zeros((5, 6), np.uint8)
    img[:, 3:] = 255
    g = image.gradient_magnitude(img)
    assert g.max() == 4 * 255 and g[:, 0].max() == 0


# ---- eq. (1)-(7) -------------------------------------------------------------------------------


def _segment_reference(ref, other, labels, s, d, direction, bins):
    """NCC, GSAD, NMI of one segment at one disparity, straight from the equations."""
    ys, xs = np.nonzero(labels == s)
    cols = np.clip(xs - direction * d, 0, ref.shape[1] - 1)
    l = ref[ys, xs].astype(float)
    r = other[ys, cols].astype(float)
    num = np.sum((l - l.mean()) * (r - r.mean()))
    den = math.sqrt(np.sum((l - l.mean()) ** 2) * np.sum((r - r.mean()) ** 2))
    ncc = max(0.0, num / den) if den > 0 else 0.0
    gl, gr = image.gradient_magnitude(ref), image.gradient_magnitude(other)
    gsad = np.abs(gl[ys, xs] - gr[ys, cols]).sum()
    bl = (ref[ys, xs].astype(int) * bins) // 256
    br = (other[ys, cols].astype(int) * bins) // 256
    joint, _, _ = np.histogram2d(bl, br, bins=bins, range=[[0, bins], [0, bins]])
    p = joint / joint.sum()

    def H(q):
        q = q[q > 0]
        return float(-(q * np.log2(q)).sum())

    hx, hy, hxy = H(p.sum(axis=1)), H(p.sum(axis=0)), H(p.ravel())
    nmi = min(1.0, max(0.0, (hx + hy - hxy) / math.sqrt(hx * hy))) if hx * hy > 0 else 0.0
    return ncc, gsad, nmi


@pytest.mark.parametrize("direction", [+1, -1])
def test_segment_costs_match_the_equations(direction):
    left, right = shifted_pair(23, 37, 4, seed=2)
    ref, other = (left, right) if direction > 0 else (right, left)
    labels = grid_labels(23, 37, 6)
    D, B = 9, 16
    c = cost.segment_costs(ref, other, image.gradient_magnitude(ref), image.gradient_magnitude(other), labels, direction, D, B)
    for s in (0, 5, int(labels.max())):
        gsads = []
        for d in range(D):
            ncc, gsad, nmi = _segment_reference(ref, other, labels, s, d, direction, B)
            gsads.append(gsad)
            assert c.ncc[s, d] == pytest.approx(ncc, abs=1e-12)
            assert c.nmi[s, d] == pytest.approx(nmi, abs=1e-12)
        gmax = max(gsads)
        np.testing.assert_allclose(c.igsad[s], [1 - g / gmax for g in gsads], atol=1e-12)


def test_partner_columns_clamp_to_the_border():
    np.testing.assert_array_equal(cost.partner_columns(6, 2, +1), [0, 0, 0, 1, 2, 3])
    np.testing.assert_array_equal(cost.partner_columns(6, 2, -1), [2, 3, 4, 5, 5, 5])


def test_flat_segments_have_zero_ncc_nmi_and_full_igsad():
    flat = np.full((8, 12), 100, np.uint8)
    labels = np.zeros((8, 12), np.int32)
    g = image.gradient_magnitude(flat)
    c = cost.segment_costs(flat, flat, g, g, labels, +1, 4, 16)
    assert np.all(c.ncc == 0) and np.all(c.nmi == 0) and np.all(c.igsad == 1)


def test_anticorrelated_ncc_is_clamped_to_zero():
    left = texture(10, 10, seed=1)
    right = (255 - left).astype(np.uint8)
    labels = np.zeros((10, 10), np.int32)
    c = cost.segment_costs(left, right, image.gradient_magnitude(left), image.gradient_magnitude(right), labels, +1, 1, 16)
    assert c.ncc[0, 0] == 0.0
    assert c.nmi[0, 0] > 0.9  # NMI does not care about the sign of the relation


def test_data_cost_2_is_eq_9():
    c = cost.SegmentCosts(ncc=np.zeros((1, 2)), igsad=np.array([[0.2, 1.0]]), nmi=np.array([[0.6, 0.0]]), pixels=np.array([4]))
    np.testing.assert_allclose(c.dc2(0.25), [[0.25 * 0.6 + 0.75 * 0.2, 0.75]])


# ---- FIS + WTA -----------------------------------------------------------------------------------


def test_wta_ties_go_to_the_smaller_disparity(fis):
    # equal costs at every d -> equal scores -> d = 0
    c = cost.SegmentCosts(ncc=np.full((2, 5), 0.7), igsad=np.full((2, 5), 0.9), nmi=np.full((2, 5), 0.8), pixels=np.array([9, 9]))
    dec = wta.fis_winner_take_all(c, fis, 0.5, 0, "fast")
    np.testing.assert_array_equal(dec.disparity, [0, 0])
    # a tie between d = 3 and d = 1 (both best) -> 1
    c.ncc[0, [1, 3]] = 0.95
    dec = wta.fis_winner_take_all(c, fis, 0.5, 0, "fast")
    assert dec.disparity[0] == 1


def test_candidates_rank_by_fis_at_the_nearest_lut_node(fis):
    rng = np.random.default_rng(0)
    c = cost.SegmentCosts(ncc=rng.random((3, 10)), igsad=rng.random((3, 10)), nmi=rng.random((3, 10)), pixels=np.ones(3, int))
    N = 17  # a coarse table, so that many (segment, d) share a node and the d tie-break matters
    cand = wta.select_candidates(c, fis, 4, "fast", lut_size=N)

    def node(x):  # FisLut::lookup_nearest on the Q16 input, written out in plain integers
        q = min(int(np.floor(x * 65536 + 0.5)), 65536)
        return (q * (N - 1) + 32768) >> 16

    for s in range(3):
        key = [int(np.floor(fis.evaluate(node(c.ncc[s, d]) / (N - 1), node(c.igsad[s, d]) / (N - 1)) * 65536 + 0.5))
               for d in range(10)]
        expected = sorted(range(10), key=lambda d: (-key[d], d))[:4]
        assert list(cand[s]) == expected
    dec = wta.fis_winner_take_all(c, fis, 0.5, 4, "fast", lut_size=N)
    full = fis.evaluate_many(c.ncc.ravel(), c.dc2(0.5).ravel()).reshape(3, 10)
    for s in range(3):
        assert dec.disparity[s] in cand[s]
        best = max(cand[s], key=lambda d: (full[s, d], -d))
        assert dec.disparity[s] == best
        assert dec.score[s] == pytest.approx(full[s, best], abs=1e-9)


def test_nearest_node_is_the_firmware_integer_rounding():
    # (min(q, 65536) * (N-1) + 32768) >> 16 for N = 257: halves round up, inputs above 1 clamp
    q = np.array([0, 127, 128, 255, 256, 65535, 65536, 70000])
    np.testing.assert_array_equal(wta.nearest_node(q, 257), [0, 0, 1, 1, 1, 256, 256, 256])


def test_q16_igsad_is_the_firmware_truncation():
    gsad = np.array([[0.0, 3.0, 7.0, 10.0]])
    c = cost.SegmentCosts(ncc=np.array([[0.0, 0.5, 1.0, 0.25]]), igsad=1 - gsad / 10, nmi=np.zeros((1, 4)),
                          pixels=np.array([4]), gsad=gsad)
    ncc, igsad = wta.q16_inputs(c)
    np.testing.assert_array_equal(ncc, [[0, 32768, 65536, 16384]])
    inv = 65536.0 / 10.0
    np.testing.assert_array_equal(igsad, [[65536 - int(g * inv) for g in gsad[0]]])


def test_k_zero_or_at_least_d_means_all_disparities(fis):
    c = cost.SegmentCosts(ncc=np.zeros((1, 6)), igsad=np.zeros((1, 6)), nmi=np.zeros((1, 6)), pixels=np.ones(1, int))
    for k in (0, 6, 9):
        np.testing.assert_array_equal(wta.select_candidates(c, fis, k), [np.arange(6)])


def test_unknown_engine_is_rejected(fis):
    with pytest.raises(ValueError, match="unknown FIS engine"):
        wta.fis_scores(fis, np.zeros(2), np.zeros(2), "lut")


def test_paint_segments():
    labels = np.array([[0, 0, 1], [2, 2, 1]])
    out = wta.paint_segments(labels, np.array([3, -1, 7]))
    np.testing.assert_array_equal(np.isnan(out), [[False, False, True], [False, False, True]])
    assert out[0, 0] == 3 and out[1, 0] == 7


# ---- eq. (13) ---------------------------------------------------------------------------------------


def test_left_right_check():
    n = np.nan
    left = np.array([[0.0, 1.0, 2.0, 2.0, 5.0, n]])
    right = np.array([[0.0, 1.0, 2.0, 4.0, n, 1.0]])
    out, mask = lrcheck.left_right_check(left, right, max_diff=1)
    # x=0: d 0 -> xr 0 (0) ok; x=1: d 1 -> xr 0 (0) ok (|1-0| <= 1); x=2: d 2 -> xr 0 (0): |2| > 1;
    # x=3: d 2 -> xr 1 (1) ok; x=4: d 5 -> xr -1 outside; x=5 invalid
    np.testing.assert_array_equal(mask, [[True, True, False, True, False, False]])
    np.testing.assert_array_equal(np.isnan(out), ~mask)
    _, strict = lrcheck.left_right_check(left, right, max_diff=0)
    np.testing.assert_array_equal(strict, [[True, False, False, False, False, False]])


def test_left_right_check_partner_invalid():
    out, mask = lrcheck.left_right_check(np.array([[0.0, 1.0]]), np.array([[np.nan, 1.0]]), 1)
    assert not mask.any() and np.isnan(out).all()


# ---- eq. (14)-(15) --------------------------------------------------------------------------------


def _random_map(h, w, seed, D=6, invalid=0.2):
    rng = np.random.default_rng(seed)
    d = rng.integers(0, D, (h, w)).astype(float)
    d[rng.random((h, w)) < invalid] = np.nan
    return d


def test_retry_keeps_the_first_consistent_candidate_best_score_first():
    # docs/algorithm.md 5b, the firmware test LrRetry.TriesTheOtherCandidatesBestFirst... in float: segment 1
    # (10 x 4 px at x >= 20) lost its winner d = 5 on every pixel; d = 2 scores second and agrees with the right
    # map on 3 of 10 columns, d = 9 scores third and agrees everywhere.
    w, h = 40, 4
    labels = np.zeros((h, w), dtype=np.int32)
    labels[:, 20:30] = 1
    right = np.full((h, w), np.nan)
    right[:, 11:21] = 9.0
    right[:, 25:28] = 2.0
    lr = np.full((h, w), np.nan)
    lr[0, 3] = 1.0  # segment 0 keeps a pixel: untouched
    mask = ~np.isnan(lr)
    winner = np.array([1, 5])
    cand = np.array([[1, 2, 3], [2, 5, 9]])
    scores = np.array([[0.9, 0.6, 0.3], [0.6, 0.9, 0.3]])
    out, m, n = lrcheck.retry_rejected_segments(lr, mask, labels, winner, cand, scores, right, 1, 3, 0.7)
    assert n == 1 and np.all(out[:, 20:30] == 9.0) and m[:, 20:30].all() and np.isnan(out[:, 30:]).all()
    out, m, n = lrcheck.retry_rejected_segments(lr, mask, labels, winner, cand, scores, right, 1, 3, 0.2)
    assert n == 1 and np.all(out[:, 27:30] == 2.0) and np.isnan(out[:, 20:27]).all() and int(m.sum()) == 13
    assert lrcheck.retry_rejected_segments(lr, mask, labels, winner, cand, scores, right, 1, 1, 0.7)[2] == 0
    same, m0, n0 = lrcheck.retry_rejected_segments(lr, mask, labels, winner, cand, scores, right, 1, 0, 0.7)
    assert n0 == 0 and np.array_equal(np.isnan(same), np.isnan(lr)) and np.array_equal(m0, mask)


def test_block_entropy_and_mean_brute_force():
    d = _random_map(11, 13, 4)
    w, r = 5, 2
    E = esr.block_entropy(d, w, 16)
    M = esr.block_mean(d, w)
    for y in range(11):
        for x in range(13):
            block = d[max(0, y - r) : y + r + 1, max(0, x - r) : x + r + 1]
            v = block[~np.isnan(block)].astype(int)
            if v.size == 0:
                assert E[y, x] == 0 and np.isnan(M[y, x])
                continue
            p = np.bincount(v) / v.size
            p = p[p > 0]
            assert E[y, x] == pytest.approx(float(-(p * np.log2(p)).sum()), abs=1e-12)
            assert M[y, x] == pytest.approx(v.mean(), abs=1e-12)


def test_block_entropy_of_constant_map_is_zero_and_all_invalid_is_zero():
    assert np.all(esr.block_entropy(np.full((6, 7), 3.0), 3, 8) == 0)
    assert np.all(esr.block_entropy(np.full((6, 7), np.nan), 3, 8) == 0)


def test_esr_replaces_with_the_lower_entropy_block_mean():
    h, w = 9, 20
    left = np.full((h, w), 4.0)
    left[4, 10] = 9.0  # an outlier in a calm left block: E_l small but > 0
    right = _random_map(h, w, 7, D=12, invalid=0.0)  # noisy right map: E_r large
    out, replaced, maps = esr.entropy_selective_refinement(left, right, window=5, tau=0.5, max_disparity=16)
    assert replaced[4, 10]
    # E_l < E_r -> the left block mean (24 fours and one nine)
    assert out[4, 10] == pytest.approx((24 * 4 + 9) / 25)
    assert maps["E_l"][4, 10] < maps["E_r"][4, 10 - 9]


def test_esr_keeps_pixels_below_tau_and_invalid_pixels():
    left = np.full((7, 12), 3.0)
    left[0, 0] = np.nan
    out, replaced, _ = esr.entropy_selective_refinement(left, left.copy(), 3, 0.5, 8)
    assert not replaced.any()
    np.testing.assert_array_equal(np.isnan(out), np.isnan(left))


def test_esr_uses_the_right_block_when_it_is_calmer():
    h, w = 9, 30
    right = np.full((h, w), 2.0)
    left = _random_map(h, w, 11, D=3, invalid=0.0)
    out, replaced, maps = esr.entropy_selective_refinement(left, right, 5, 0.5, 8)
    y, x = 4, 15
    d = int(left[y, x])
    assert replaced[y, x] and maps["E_l"][y, x] > maps["E_r"][y, x - d]
    assert out[y, x] == pytest.approx(2.0)


# ---- segmentation ---------------------------------------------------------------------------------


def test_slic_labels_are_dense_connected_and_sized():
    img = texture(40, 56, seed=9, blur=2.0)
    labels = segmentation.slic(img, region_size=8, compactness=20, iterations=4, min_segment_pct=25)
    n = int(labels.max()) + 1
    assert labels.dtype == np.int32 and labels.min() == 0
    assert np.unique(labels).size == n
    assert segmentation._pieces(labels).max() + 1 == n  # one 4-connected piece per label
    assert 20 <= n <= 60
    assert np.bincount(labels.ravel()).min() >= 16


def test_label_agreement():
    a = grid_labels(16, 16, 4)
    assert segmentation.label_agreement(a, a) == 100.0
    assert segmentation.label_agreement(a, a + 7) == 100.0  # renaming does not matter
    b = grid_labels(16, 16, 8)
    assert segmentation.label_agreement(a, b) < 30.0  # under-segmentation is penalised


# ---- the whole pipeline --------------------------------------------------------------------------


def _integer_maps(r):
    return (wta.paint_segments(r.labels_left, r.dec_left.disparity), wta.paint_segments(r.labels_right, r.dec_right.disparity))


@pytest.mark.parametrize("d_true", [0, 3, 7])
def test_recovers_a_known_shift(fis, d_true):
    left, right = shifted_pair(48, 64, d_true, seed=d_true)
    r = match(left, right, small_config(), fis)
    # textured plane: every segment away from the left border (where partners are clamped) wins d
    int_l, int_r = _integer_maps(r)
    assert np.mean(int_l[:, d_true + 8 :] == d_true) > 0.97
    assert np.mean(int_r[:, : -(d_true + 8)] == d_true) > 0.97
    # the sub-pixel parabola stays within half a pixel, and near d for a true integer shift
    assert np.all(np.abs(r.disp_left_wta - int_l) <= 0.5)
    assert np.nanmean(np.abs(r.disp_left_wta[:, d_true + 8 :] - d_true)) < 0.2
    final = r.disp_esr[:, d_true + 8 :]  # the paper pipeline; densify treats d = 0 as no estimate
    assert np.nanmean(np.abs(final - d_true) <= 0.5) > 0.97
    assert np.mean(~np.isnan(final)) > 0.9


def test_integer_mode_paints_integers(fis):
    left, right = shifted_pair(32, 48, 4, seed=2)
    r = match(left, right, small_config(cost__subpixel=False), fis)
    int_l, _ = _integer_maps(r)
    np.testing.assert_array_equal(r.disp_left_wta, int_l)


def test_subpixel_parabola():
    nan = np.nan
    scores = np.array(
        [
            [0.2, 0.6, 0.5, 0.1],  # winner 1: vertex (0.5 - 0.2) / (2 (1.2 - 0.7)) = 0.3
            [0.5, 0.6, 0.2, 0.1],  # winner 1: (0.2 - 0.5) / (2 * 0.5) = -0.3
            [0.6, 0.5, 0.2, 0.1],  # winner 0: no left neighbour -> 0
            [nan, 0.6, 0.5, 0.1],  # d - 1 not a candidate -> 0
            [0.1, 0.2, 0.3, 0.9],  # winner D - 1 -> 0
            [0.59, 0.6, 0.0, 0.0],  # nearly flat to the left: (0 - 0.59) / (2 * 0.61), near -1/2
        ]
    )
    winner = np.array([1, 1, 0, 1, 3, 1])
    np.testing.assert_allclose(wta.subpixel_offset(scores, winner), [0.3, -0.3, 0, 0, 0, -0.59 / 1.22], atol=1e-12)


def test_subpixel_every_segment_scores_the_neighbours_with_the_winners_nmi(fis):
    # One segment, K = 1 candidate: the winner's neighbours are never candidates. Without the
    # fallback it stays on the whole pixel; with it the parabola runs through
    # FIS(NCC(d'), alpha NMI(winner) + (1 - alpha) IGSAD(d')) at d - 1, d, d + 1.
    ncc = np.array([[0.1, 0.5, 0.9, 0.7, 0.2]])
    igsad = np.array([[0.2, 0.6, 0.95, 0.8, 0.3]])
    nmi = np.array([[0.0, 0.0, 0.7, 0.0, 0.0]])  # NMI elsewhere must not be read
    c = cost.SegmentCosts(ncc=ncc, igsad=igsad, nmi=nmi, pixels=np.array([50]))
    plain = wta.fis_winner_take_all(c, fis, 0.2, 1, "fast", subpixel=True, subpixel_every_segment=False)
    assert plain.disparity[0] == 2 and plain.disparity_sub[0] == 2.0
    dec = wta.fis_winner_take_all(c, fis, 0.2, 1, "fast", subpixel=True, subpixel_every_segment=True)
    s = [fis.evaluate(ncc[0, d], 0.2 * 0.7 + 0.8 * igsad[0, d]) for d in (1, 2, 3)]
    expected = (s[2] - s[0]) / (2 * (2 * s[1] - s[0] - s[2]))
    assert 0 < expected < 0.5  # the right neighbour scores higher: the vertex moves right
    assert dec.disparity[0] == 2
    assert dec.disparity_sub[0] == pytest.approx(2 + expected, abs=1e-9)


def test_recovers_two_planes_with_given_labels(fis):
    left, right, gt = two_plane_pair(48, 72, 2, 9, seed=3)
    labels = grid_labels(48, 72, 8)  # segment boundaries on the plane boundary (row 24)
    r = match(left, right, small_config(), fis, labels, labels)
    assert r.labels_given
    int_l, _ = _integer_maps(r)
    assert np.mean((int_l == gt)[:, 16:]) > 0.97
    np.testing.assert_array_equal(r.labels_left, labels)


def test_lr_check_keeps_the_interior_and_drops_the_left_border(fis):
    # left pixels x < d have no partner in the right image (x - d < 0): eq. (13) must drop them
    left, right = shifted_pair(40, 64, 8, seed=4)
    r = match(left, right, small_config(), fis)
    assert np.mean(r.lr_mask[:, 16:]) > 0.95
    assert np.mean(r.lr_mask[:, :4]) < 0.2


def test_esr_disabled_keeps_the_lr_map(fis):
    left, right = shifted_pair(32, 48, 3, seed=1)
    r = match(left, right, small_config(esr__enabled=False), fis)
    np.testing.assert_array_equal(np.isnan(r.disp_esr), np.isnan(r.disp_lr))
    assert not r.esr_replaced.any()


def test_engines_agree(fis):
    # the vectorised twin and ControlSystemSimulation give the same decisions
    left, right = shifted_pair(24, 32, 2, seed=6)
    cfg = small_config(cost__max_disparity=6, cost__nmi_candidates=3)
    labels = grid_labels(24, 32, 8)
    a = match(left, right, cfg, fis, labels, labels, engine="fast")
    b = match(left, right, cfg, fis, labels, labels, engine="skfuzzy")
    np.testing.assert_array_equal(a.dec_left.disparity, b.dec_left.disparity)
    np.testing.assert_allclose(a.dec_left.score, b.dec_left.score, atol=1e-9)


def test_bad_inputs_are_fatal(fis):
    from fuzzyctl.errors import FatalError

    left, right = shifted_pair(16, 20, 1)
    with pytest.raises(FatalError, match="equal size"):
        match(left, right[:, :-1], small_config(), fis)
    with pytest.raises(FatalError, match="labels_left: labels are"):
        match(left, right, small_config(), fis, np.zeros((3, 3), np.int32), None)
    with pytest.raises(FatalError, match="dense"):
        match(left, right, small_config(), fis, np.full((16, 20), 2, np.int32), None)


def test_partner_of_a_subpixel_disparity_is_rounded_half_up():
    # x - round(d) (the firmware's partner_x): x = 3, d = 2.5 -> partner 0; x = 4, d = 2.4375 -> 2
    left = np.array([[np.nan, np.nan, np.nan, 2.5, 2.4375]])
    right = np.array([[2.0, 3.5, 9.0, 9.0, 9.0]])
    out, mask = lrcheck.left_right_check(left, right, 1)
    np.testing.assert_array_equal(mask, [[False, False, False, True, False]])
    right2 = np.array([[9.0, 9.0, 3.4375, 9.0, 9.0]])
    _, mask2 = lrcheck.left_right_check(left, right2, 1)
    np.testing.assert_array_equal(mask2, [[False, False, False, False, True]])
    assert list(lrcheck.round_half_up(np.array([0.5, 1.49, 2.5, 3.0]))) == [1, 1, 3, 3]


def test_block_entropy_bins_are_rounded_disparities():
    d = np.array([[1.4, 1.6, 2.4]])  # bins 1, 2, 2 -> entropy of (1/3, 2/3)
    E = esr.block_entropy(d, 3, 16)
    p = np.array([1 / 3, 2 / 3])
    assert E[0, 1] == pytest.approx(float(-(p * np.log2(p)).sum()))


def test_boundary_refinement_gives_a_straddling_segments_far_side_back():
    # docs/algorithm.md 4b; the scene of the firmware test Boundary.GivesAStraddlingSegments...
    from fuzzyctl.reference import boundary

    rng = np.random.default_rng(5)
    w, h, db, df = 96, 64, 4, 12
    bg, fg = rng.integers(0, 256, (h, w + 32)), rng.integers(0, 256, (h, w + 32))
    sx0, sx1, sy0, sy1, strip = 40, 60, 20, 44, 5
    yy, xx = np.mgrid[0:h, 0:w]
    in_l = (yy >= sy0) & (yy < sy1) & (xx >= sx0) & (xx < sx1)
    left = np.where(in_l, fg[:, :w], bg[:, :w]).astype(np.uint8)
    in_r = (yy >= sy0) & (yy < sy1) & (xx + df >= sx0) & (xx + df < sx1)
    right = np.where(in_r, fg[:, df : df + w], bg[:, db : db + w]).astype(np.uint8)
    disp = np.full((h, w), float(db))
    disp[sy0:sy1, sx0 : sx1 + strip] = df
    out = boundary.refine(disp, boundary.census(left, 2), boundary.census(right, 2), +1, 7, 1.0, 4, 1, 1, 24)
    rows = slice(sy0 + 3, sy1 - 3)
    assert np.all(out[rows, sx1 + 2 : sx1 + strip] == db)
    assert np.all(out[rows, sx0 + 3 : sx1 - 3] == df)
    unchanged = boundary.refine(disp, boundary.census(left, 2), boundary.census(right, 2), +1, 7, 1.0, 4, 16, 1, 24)
    np.testing.assert_array_equal(unchanged, disp)


def test_census_bits_and_popcount():
    from fuzzyctl.reference import boundary

    img = np.array([[5, 1, 9], [2, 5, 7], [5, 3, 4]], dtype=np.uint8)
    c = boundary.census(img, 1)
    # centre 5: neighbours row-major (1,1)..: 5,1,9,2,7,5,3,4 -> darker: 1,2,3,4 at bits 1,3,6,7
    assert c[1, 1] == (1 << 1) | (1 << 3) | (1 << 6) | (1 << 7)
    v = np.array([0, 1, 0xFFFFFF, 0x800001, 0xFFFFFFFF], dtype=np.uint32)
    assert boundary._popcount(v).tolist() == [0, 1, 24, 2, 32]
