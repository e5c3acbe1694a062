"""The FIS of eq. (10)-(12) / Table I: definition, scikit-fuzzy system, vectorised twin, firmware.

Acceptance test of the FIS issue: on >= 1000 seeded random pairs plus corners/edges, the
firmware's fixed-point LUT is within 0.01 (1 % of the output range [0, 1]) of scikit-fuzzy.
"""

from __future__ import annotations

import numpy as np
import pytest

from fuzzyctl import fis as fismod
from fuzzyctl.errors import FatalError
from fuzzyctl.fischeck import EXACT_TOLERANCE, LUT_TOLERANCE, check_points

N_RANDOM = 1000
SEED = 20240601


@pytest.fixture(scope="module")
def points():
    return check_points(N_RANDOM, SEED)


@pytest.fixture(scope="module")
def skfuzzy_out(fis, points):
    """scikit-fuzzy ControlSystemSimulation at the check points — the oracle."""
    return fis.evaluate_many(*points)


# ---- the definition --------------------------------------------------------------------------


def test_definition_shape(fis):
    d = fis.defn
    assert d.name == "paper-table-1"
    assert len(d.rules) == 36
    assert [r.number for r in d.rules] == list(range(1, 37))
    assert (len(d.dc1.terms), len(d.dc2.terms), len(d.output.terms)) == (6, 6, 15)
    assert d.dc1.term_names() == ["poor", "very_bad", "bad", "average", "good", "very_good"]
    assert d.output.term_names()[0] == "worst" and d.output.term_names()[-1] == "best"


def test_rule_27_is_good_bad_acceptable(fis):
    # printed as a second "26" in the paper's Table I
    r = fis.defn.rule(27)
    assert (r.dc1, r.dc2, r.out) == ("good", "bad", "acceptable")


def test_table_covers_every_input_pair_once(fis):
    d = fis.defn
    pairs = {(r.dc1, r.dc2) for r in d.rules}
    assert pairs == {(a, b) for a in d.dc1.term_names() for b in d.dc2.term_names()}


@pytest.mark.parametrize("var", ["dc1", "dc2"])
def test_input_memberships_are_a_partition_of_unity(fis, var):
    d = fis.defn
    u = d.input_universe
    total = sum(t.membership(u) for t in getattr(d, var).terms)
    np.testing.assert_allclose(total, 1.0, atol=1e-9)


def test_output_memberships_cover_the_universe(fis):
    d = fis.defn
    u = d.output_universe
    total = sum(t.membership(u) for t in d.output.terms)
    assert total.min() > 0.99  # Ruspini up to the 10-digit rounding of k/14 in fis.toml
    assert total.max() < 1.0 + 1e-6


# ---- validation errors ------------------------------------------------------------------------

GOOD = (fismod.paths.fis_file()).read_text()


def _parse(text):
    return fismod.parse_definition(text, "test.toml")


def test_default_definition_parses():
    assert len(_parse(GOOD).rules) == 36


def test_unknown_term_in_rule_is_named():
    bad = GOOD.replace('[12, "very_bad", "very_good", "average"]', '[12, "very_bad", "very_goood", "average"]')
    with pytest.raises(FatalError, match=r"test.toml: rule 12: unknown dc2 term 'very_goood'"):
        _parse(bad)


def test_unknown_output_term_is_named():
    bad = GOOD.replace('[36, "very_good", "very_good", "best"]', '[36, "very_good", "very_good", "bestest"]')
    with pytest.raises(FatalError, match=r"rule 36: unknown score term 'bestest'"):
        _parse(bad)


def test_duplicate_rule_pair_is_named():
    bad = GOOD.replace('[27, "good", "bad", "acceptable"]', '[27, "good", "very_bad", "acceptable"]')
    with pytest.raises(FatalError, match=r"rule 27: \(good, very_bad\) already has a consequent in rule 26"):
        _parse(bad)


def test_duplicate_rule_number_is_named():
    bad = GOOD.replace('[27, "good", "bad", "acceptable"]', '[26, "good", "bad", "acceptable"]')
    with pytest.raises(FatalError, match=r"rule number 26 is used twice"):
        _parse(bad)


@pytest.mark.parametrize(
    "replacement, message",
    [
        ('{ name = "bad", mf = "trimf", params = [0.2, 0.4] }', r"inputs.dc1 term 'bad': trimf needs params = \[3 numbers\]"),
        ('{ name = "bad", mf = "trimf", params = [0.6, 0.4, 0.2] }', r"inputs.dc1 term 'bad': params .* must be non-decreasing"),
        ('{ name = "bad", mf = "gaussmf", params = [0.4, 0.1] }', r"inputs.dc1 term 'bad': mf = 'gaussmf'"),
        ('{ name = "bad", mf = "trimf", params = [0.4, 0.4, 0.4] }', r"empty support"),
        ('{ name = "bad", mf = "trimf", params = [0.2, "x", 0.6] }', r"trimf needs params"),
    ],
)
def test_bad_membership_params_are_named(replacement, message):
    bad = GOOD.replace('{ name = "bad", mf = "trimf", params = [0.2, 0.4, 0.6] }', replacement, 1)
    assert bad != GOOD
    with pytest.raises(FatalError, match=message):
        _parse(bad)


def test_duplicate_term_name_is_named():
    bad = GOOD.replace('{ name = "poor", mf = "trimf", params = [0, 0, 0.2] }', '{ name = "bad", mf = "trimf", params = [0, 0, 0.2] }', 1)
    with pytest.raises(FatalError, match=r"inputs.dc1 term 'bad' is defined twice"):
        _parse(bad)


def test_invalid_toml_and_missing_file(tmp_path):
    with pytest.raises(FatalError, match=r"test.toml: not valid TOML"):
        _parse("rules = [")
    with pytest.raises(FatalError, match=r"cannot read FIS definition .*nope.toml"):
        fismod.load_definition(tmp_path / "nope.toml")


# ---- scikit-fuzzy system -------------------------------------------------------------------------


def _centroid_of_term(term):
    a, b, c = term.params  # all output terms are triangles: centroid (a + b + c) / 3
    return (a + b + c) / 3.0


def test_at_term_centres_the_output_is_the_consequent_centroid(fis):
    # At (k/5, l/5) exactly one rule fires (with strength 1), so the output is the centroid of
    # that rule's consequent term alone.
    d = fis.defn
    centres = np.linspace(0, 1, 6)
    a, b = np.meshgrid(centres, centres, indexing="ij")
    out = fis.evaluate_many(a.ravel(), b.ravel()).reshape(a.shape)
    for r in d.rules:
        i, j = d.dc1.index(r.dc1), d.dc2.index(r.dc2)
        expected = _centroid_of_term(d.output.terms[d.output.index(r.out)])
        assert out[i, j] == pytest.approx(expected, abs=1e-6), f"rule {r.number}"


def test_scalar_and_array_simulation_agree(fis):
    a = np.array([0.0, 0.13, 0.5, 0.77, 1.0])
    b = np.array([0.9, 0.42, 0.5, 0.08, 1.0])
    arr = fis.evaluate_many(a, b)
    for x, y, v in zip(a, b, arr):
        assert fis.evaluate(x, y) == pytest.approx(v, abs=1e-12)


def test_module_level_evaluate():
    assert 0.0 <= fismod.evaluate(0.5, 0.5) <= 1.0


def test_output_is_monotone_along_the_diagonal(fis):
    t = np.linspace(0, 1, 41)
    out = fis.evaluate_many(t, t)
    assert np.all(np.diff(out) >= -1e-9)


def test_vectorised_twin_matches_scikit_fuzzy(fis, points, skfuzzy_out):
    # The desktop reference uses the twin for speed; it must be scikit-fuzzy's arithmetic.
    fast = fis.evaluate_fast(*points)
    assert np.max(np.abs(fast - skfuzzy_out)) <= 1e-9


def test_twin_cross_check_passes(fis, points):
    assert fis.cross_check(*points, samples=50) <= 1e-9


# ---- the firmware: fixed-point LUT and double Mamdani vs scikit-fuzzy -----------------------------


@pytest.mark.firmware
def test_firmware_lut_within_one_percent(firmware_bin, points, skfuzzy_out):
    from fuzzyctl.firmware import fis_eval

    dc1, dc2 = points
    assert len(dc1) >= N_RANDOM + 4
    lut, _exact = fis_eval(firmware_bin, dc1, dc2)
    err = np.abs(lut - skfuzzy_out)
    i = int(np.argmax(err))
    assert err[i] <= LUT_TOLERANCE, f"max |LUT - skfuzzy| = {err[i]:.4g} at ({dc1[i]}, {dc2[i]})"


@pytest.mark.firmware
def test_firmware_exact_matches_scikit_fuzzy(firmware_bin, points, skfuzzy_out):
    from fuzzyctl.firmware import fis_eval

    dc1, dc2 = points
    _lut, exact = fis_eval(firmware_bin, dc1, dc2)
    err = np.abs(exact - skfuzzy_out)
    i = int(np.argmax(err))
    assert err[i] <= EXACT_TOLERANCE, f"max |exact - skfuzzy| = {err[i]:.3g} at ({dc1[i]}, {dc2[i]})"


@pytest.mark.firmware
def test_fis_check_command_passes(firmware_bin, capsys):
    from fuzzyctl.cli import main

    assert main(["fis", "check", "--points", "200", "--bin", str(firmware_bin)]) == 0
    assert "max abs error" in capsys.readouterr().out


def test_check_points_include_corners_and_edges():
    a, b = check_points(10, 0)
    pts = set(zip(a.tolist(), b.tolist()))
    for corner in ((0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0), (0.5, 0.0), (1.0, 0.25)):
        assert corner in pts
    assert len(a) >= 10 + 4 * 21 - 4
