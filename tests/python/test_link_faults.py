"""Small versions of tests/python/stress_link.py (the lead runs the full ones): transfers through
the fault relay (1 % dropped + 1 % corrupted bytes) never accept corrupted data; SIGKILL during
config pushes always restarts with the old or the new config; log pull throughput through the
throttled relay."""

from __future__ import annotations

import pytest

pytest.importorskip("serial")
pytest.importorskip("cobs")

import stress_link  # noqa: E402

pytestmark = [pytest.mark.firmware, pytest.mark.slow]


@pytest.fixture(autouse=True)
def _bin(firmware_bin, monkeypatch):
    monkeypatch.setenv("FUZZYSTEREO_BIN", str(firmware_bin))


def test_faulty_link_never_accepts_corrupted_data(tmp_path):
    r = stress_link.run_faults(16, drop=0.01, corrupt=0.01, seed=3, work=tmp_path, log=lambda *_: None)
    assert r["silent_corruption"] == 0
    assert r["ok"] + r["clean_error"] == 16
    assert r["ok"] >= 12, r  # retries recover most transfers at 2 % byte errors
    assert r["relay"]["to_device"]["corrupted"] > 0 and r["relay"]["to_host"]["dropped"] > 0  # faults did happen


def test_power_cut_during_config_push(tmp_path):
    r = stress_link.run_powercut(8, seed=5, work=tmp_path, log=print)
    assert r["bad"] == 0, r


def test_log_pull_throughput_115200(tmp_path):
    r = stress_link.run_throughput(115200, 24, work=tmp_path)
    assert r["verified"]
    assert r["efficiency"] >= 0.8, r
