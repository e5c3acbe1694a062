"""fuzzyctl track-replay: the float reference of the tracker's Kalman filter (paper eq. 26-32) against the
firmware's recorded states, and what-if settings on the same measurements."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path
from typing import Any

import pytest

from fuzzyctl.cli import main
from fuzzyctl.errors import FatalError
from fuzzyctl.reference.tracker import KalmanParams, replay_frames
from fuzzyctl.trackreplay import parse_overrides, track_replay


@pytest.fixture(scope="module")
def demo_record(firmware_bin, common_dir, tmp_path_factory) -> Path:
    """100 frames of the demo mission (static and moving obstacles), recorded by the firmware."""
    rec = tmp_path_factory.mktemp("replay") / "rec"
    p = subprocess.run([str(firmware_bin), "run", "--source", f"sim:{common_dir / 'sim/scenes/demo.toml'}", "--quiet",
                        "--max-frames", "100", "--record", str(rec), "--snapshot-every", "0"],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    return rec


def test_the_reference_filter_reproduces_the_firmwares_states(demo_record: Path) -> None:
    r = track_replay([demo_record])
    a = r["agreement"]
    assert a["states"] > 200 and a["updates"] > 80  # the run tracked something
    # The same filter in double precision on both sides (Eigen / numpy): rounding only.
    assert a["max_pos_diff_m"] < 1e-6, a
    assert a["max_vel_diff_mps"] < 1e-6, a
    assert r["movers"] is not None and r["movers"]["n"] > 0  # the demo's movers were measured
    assert r["movers"]["replay_pos_rmse_m"] == pytest.approx(r["movers"]["firmware_pos_rmse_m"], abs=1e-9)


def record_suite_run(firmware_bin, rec: Path, config: Path | None = None) -> Path:
    """Records closed-loop suite scenario 0 of seed 901 (movers; its tracks trip the maneuver switch) under `rec`."""
    args = [str(firmware_bin), "sim", "suite", "--count", "100", "--blocked", "0", "--seed", "901", "--only", "0",
            "--jobs", "1", "--record", str(rec), "--snapshot-every", "0"]
    if config is not None:
        args += ["--config", str(config)]
    p = subprocess.run(args, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    return rec / "suite-901-0"


@pytest.fixture(scope="module")
def suite_record(firmware_bin, tmp_path_factory) -> Path:
    return record_suite_run(firmware_bin, tmp_path_factory.mktemp("replay_suite"))


def assert_replay_agrees_and_setting_matters(run: Path, off: dict[str, Any]) -> None:
    """The reference replays the firmware's filter on `run`, and the setting `off` turns off moves it by centimetres."""
    r = track_replay([run])
    # Tracks that coasted for seconds before their next update (covariance grown to 10^3 m^2) make that
    # update ill-conditioned: the two implementations then differ in the 5th-6th digit, not more.
    assert r["agreement"]["updates"] > 100
    assert r["agreement"]["max_pos_diff_m"] < 1e-4, r["agreement"]
    assert r["agreement"]["max_vel_diff_mps"] < 1e-4, r["agreement"]
    moved = track_replay([run], off)
    assert moved["agreement"]["max_pos_diff_m"] > 1e-2


def test_the_reference_reproduces_the_maneuver_switch_of_a_suite_run(suite_record: Path) -> None:
    # The switch matters on this run: never switching moves the states by centimetres.
    assert_replay_agrees_and_setting_matters(suite_record, {"tracker.maneuver_nis": 100.0})


def test_another_setting_changes_the_replayed_filter(demo_record: Path) -> None:
    # The check above can fail: a replay that ignored its settings, or the firmware's states, would not move here.
    r = track_replay([demo_record], parse_overrides(["tracker.velocity_measurement=false"]))
    assert r["agreement"]["max_pos_diff_m"] > 1e-3
    r2 = track_replay([demo_record], parse_overrides(["tracker.accel_sigma_steady_mps2 = 0.6"]))
    assert r2["agreement"]["max_pos_diff_m"] > 1e-3


def test_the_cli_prints_the_agreement_and_writes_json(demo_record: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "r.json"
    assert main(["track-replay", str(demo_record), "--json", str(out)]) in (0, None)
    text = capsys.readouterr().out
    assert "reference vs firmware" in text and "moving obstacles" in text and "position NIS" in text
    assert json.loads(out.read_text())["agreement"]["max_pos_diff_m"] < 1e-6


def _mover_frames(n: int, noise_m: float) -> list[dict]:
    """A track of a mover at 0.3 m/s along x, measured every 0.2 s with a +-noise_m zigzag across its path."""
    frames = []
    for k in range(n):
        t = 0.2 * k
        raw = [1.0 + 0.3 * t, (noise_m if k % 2 else -noise_m)]
        frames.append({"frame": k, "t": t, "true_pose": [0.0, 0.0, 0.0],
                       "tracks": [{"id": 7, "age_s": 0.0, "hits": k + 1, "last": raw, "mvar": noise_m ** 2,
                                   "p": raw, "v": [0.0, 0.0]}]})
    return frames


def test_the_replayed_filter_learns_a_constant_velocity() -> None:
    states = replay_frames(_mover_frames(40, 0.05), KalmanParams())
    last = states[-1]
    assert last.hits == 40
    assert math.hypot(last.ref_v[0] - 0.3, last.ref_v[1]) < 0.1  # issue 5: within 0.1 m/s after 10 frames
    # filtered cross-track error below the raw +-0.05 m zigzag over the last 20 updates
    assert max(abs(s.ref_p[1]) for s in states[-20:]) < 0.05


def test_a_mover_record_gives_the_targets_figures(tmp_path: Path) -> None:
    d = tmp_path / "rec"
    d.mkdir()
    (d / "run.json").write_text(json.dumps({"world": {"obstacles": [
        {"id": 0, "shape": "circle", "radius": 0.2, "x": 1.0, "y": 0.0, "vx": 0.3, "vy": 0.0}]}, "result": {}}))
    (d / "config.toml").write_text("[tracker]\nvelocity_measurement = false\n")
    (d / "frames.jsonl").write_text("\n".join(json.dumps(f) for f in _mover_frames(40, 0.05)) + "\n")
    m = track_replay([d])["movers"]
    assert m["n"] == 40
    assert m["raw_pos_rmse_m"] == pytest.approx(0.05, abs=1e-9)
    assert m["firmware_pos_rmse_m"] == pytest.approx(0.05, abs=1e-9)  # the fake record's "p" is the raw measurement
    assert m["replay_pos_rmse_m"] < 0.05  # the filter averages the white zigzag
    assert m["replay_vel_after10_p95_mps"] < 0.1
    # A robot's own record has no world: no truth figures, the agreement and the NIS all the same.
    (d / "run.json").write_text(json.dumps({"source": "libcamera", "result": {}}))
    r = track_replay([d])
    assert r["movers"] is None and r["nis"]["n"] == 40 - 3 and r["agreement"]["updates"] == 40


def test_a_higher_floor_of_r_makes_the_innovations_smaller(suite_record: Path) -> None:
    base = track_replay([suite_record])
    assert base["nis"]["n"] > 50 and base["nis"]["mean"] > 0
    floored = track_replay([suite_record], parse_overrides(["loop.meas_sigma_floor_m = 0.2"]))
    assert floored["nis"]["mean"] < base["nis"]["mean"]  # R grew for every measurement below 0.2 m std
    assert floored["agreement"]["max_pos_diff_m"] > 1e-3
    with pytest.raises(FatalError, match="below the record's own floor"):
        track_replay([suite_record], parse_overrides(["loop.meas_sigma_floor_m = 0.01"]))


def test_bad_settings_and_old_records_are_named(tmp_path: Path) -> None:
    with pytest.raises(FatalError, match="KEY must be one of"):
        parse_overrides(["tracker.gate_m=1.0"])
    with pytest.raises(FatalError, match="expected tracker.KEY=VALUE"):
        parse_overrides(["accel_sigma_mps2=1"])
    with pytest.raises(FatalError, match="tracker.maneuver_nis"):
        parse_overrides(["tracker.maneuver_nis=-1"])
    with pytest.raises(FatalError, match="loop.meas_sigma_floor_m"):
        parse_overrides(["loop.meas_sigma_floor_m=5"])
    with pytest.raises(FatalError, match="expected tracker.KEY=VALUE"):
        parse_overrides(["loop.stuck_after_s=5"])
    frames = _mover_frames(3, 0.05)
    del frames[1]["tracks"][0]["mvar"]
    with pytest.raises(FatalError, match="frame 1, track 7: no 'mvar'"):
        replay_frames(frames, KalmanParams())


def test_the_reference_reproduces_the_coast_decay(firmware_bin, tmp_path: Path) -> None:
    # [tracker] coast_decay_s (session 47): tracks that missed the previous frame predict with a decaying velocity,
    # on both sides; the record's own config carries the setting.
    cfg = tmp_path / "decay.toml"
    cfg.write_text("[tracker]\ncoast_decay_s = 0.5\n")
    run = record_suite_run(firmware_bin, tmp_path / "rec", cfg)
    # without the decay the replay's coasting tracks drift off the firmware's
    assert_replay_agrees_and_setting_matters(run, {"tracker.coast_decay_s": 0.0})
    # coast_decay_unseen_only needs the camera's view, which the record does not hold: refused by name
    conf = run / "config.toml"
    text = conf.read_text()
    assert "coast_decay_unseen_only = false" in text
    conf.write_text(text.replace("coast_decay_unseen_only = false", "coast_decay_unseen_only = true"))
    with pytest.raises(FatalError, match="coast_decay_unseen_only"):
        track_replay([run])
