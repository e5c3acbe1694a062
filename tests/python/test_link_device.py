"""Every `fuzzyctl --port` command against the real firmware binary: `fuzzystereo run` on the
simulator source with sim motors and its serial link on a pseudo-terminal."""

from __future__ import annotations

import json
import os
import tomllib

import pytest

pytest.importorskip("serial")
pytest.importorskip("cobs")

from linkdev import Device, fuzzyctl  # noqa: E402

pytestmark = pytest.mark.firmware


@pytest.fixture()
def device(firmware_bin, tmp_path):
    d = Device(firmware_bin, tmp_path / "state", mode="run")
    d.start()
    yield d
    d.stop()


def ok(*args):
    r = fuzzyctl(*args)
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout


def test_info_reports_layout_and_config(device, common_dir):
    from fuzzyctl.link.schema import load_schema

    info = json.loads(ok("--port", device.pty, "info"))
    assert info["schema_hash"] == load_schema().hash.hex()
    assert info["config_source"] == "defaults"
    assert info["fw_version"]


def test_config_push_pull_diff_and_refusal(device, tmp_path):
    good = tmp_path / "good.toml"
    good.write_text("[esr]\nwindow = 7\ntau = 0.75\n")
    out = ok("--port", device.pty, "config", "push", str(good))
    assert "verified by the device" in out
    pulled = tmp_path / "pulled.toml"
    ok("--port", device.pty, "config", "pull", str(pulled))
    assert pulled.read_text() == good.read_text()
    assert "all resolved values equal" in ok("--port", device.pty, "config", "diff", str(good))
    other = tmp_path / "other.toml"
    other.write_text("[esr]\nwindow = 9\n")
    assert "esr.window" in ok("--port", device.pty, "config", "diff", str(other))
    # a config the local validator refuses never leaves the host
    bad = tmp_path / "bad.toml"
    bad.write_text("[esr]\nwindow = 4\n")
    r = fuzzyctl("--port", device.pty, "config", "push", str(bad))
    assert r.returncode == 2 and "esr.window" in r.stderr
    assert "OK" in ok("config", "validate", str(good))
    # the device refuses one its own validator rejects: sent raw, bypassing the host check
    from fuzzyctl.link.device import config_push
    from fuzzyctl.link.transport import DeviceRefused, Link

    with Link(device.pty) as link:
        link.hello()
        with pytest.raises(DeviceRefused) as e:
            config_push(link, b"[esr]\nwindow = 4\n")
        assert e.value.status_name == "INVALID_CONFIG" and "esr.window" in e.value.text
        assert link.hello()["config_source"] == "active"
    assert pulled.read_text() == (device.state_dir / "config" / "active.toml").read_text()  # old one stays


def test_logs_list_pull_resume_and_convert(device, tmp_path):
    import time

    time.sleep(1.5)  # at least one record (link.log_period_ms = 1000)
    assert "bytes" in ok("--port", device.pty, "logs", "list")
    out = tmp_path / "logs"
    txt = ok("--port", device.pty, "logs", "pull", "--out", str(out), "--format", "csv")
    assert "records verified, ok" in txt
    raw = sorted(out.glob("log_*.fsl"))[-1]
    csv = raw.with_suffix(".csv").read_text().splitlines()
    assert csv[0].startswith("t_ms,message,frame_id") and len(csv) >= 2
    # resume: cut the local copy mid-record, pull again: only the rest comes, result identical to the device file
    data = raw.read_bytes()
    raw.write_bytes(data[: len(data) // 2])
    ok("--port", device.pty, "logs", "pull", "--out", str(out))
    dev = (device.state_dir / "logs" / raw.name).read_bytes()
    assert raw.read_bytes() == dev[: len(raw.read_bytes())] and len(raw.read_bytes()) >= len(data)
    j = json.loads(ok("--port", device.pty, "logs", "pull", "--out", str(out), "--format", "json") and raw.with_suffix(".json").read_text())
    ids = [r["frame_id"] for r in j]
    assert ids == sorted(ids) and len(ids) >= 1


def test_monitor_plain_lines(device):
    out = ok("--port", device.pty, "monitor", "--count", "3", "--interval", "0.6")
    lines = [ln for ln in out.splitlines() if ln.startswith("frame ")]
    assert len(lines) == 3
    ids = [int(ln.split()[1]) for ln in lines]
    assert ids[0] < ids[-1]  # frames advance
    assert "sim:" in lines[-1] and "straight.toml" in lines[-1]  # the robot loop's telemetry


def test_estop_pause_resume(device):
    ok("--port", device.pty, "estop")
    assert json.loads(ok("--port", device.pty, "info"))["state"] == 2
    r = fuzzyctl("--port", device.pty, "resume")
    assert r.returncode == 2 and "BUSY" in r.stderr and "clear it first" in r.stderr
    ok("--port", device.pty, "clear-estop")
    ok("--port", device.pty, "pause")
    assert json.loads(ok("--port", device.pty, "info"))["state"] == 1
    ok("--port", device.pty, "resume")
    assert json.loads(ok("--port", device.pty, "info"))["state"] == 0


def test_snapshot_then_compare(device, tmp_path):
    out = tmp_path / "snap"
    ok("--port", device.pty, "snapshot", "--out", str(out))
    assert (out / "meta.json").exists() and (out / "disp_final.npy").exists()
    # The dump names the settings the loop's matcher ran with (the detection consumers' ones: the boundary
    # refinement on, 0 + 4 SLIC rounds), not [segmentation] / [boundary] of the config alone.
    cfg = tomllib.loads(json.loads((out / "meta.json").read_text())["config_toml"])
    assert cfg["boundary"]["enabled"] is True
    assert (cfg["segmentation"]["coarse_iterations"], cfg["segmentation"]["iterations"]) == (0, 4)
    r = fuzzyctl("compare", str(out), timeout=300)
    assert r.returncode in (0, 1), r.stderr  # 0/1 = compared (within / outside tolerance); 2 = could not read it
    # Each stage on the firmware's own inputs ("isolated") agrees; the end-to-end chain of a 320 x 180 robot frame
    # may drift past its tolerance (upstream segment differences propagate), which is not a failure here.
    isolated = [line for line in r.stdout.splitlines() if "isolated" in line]
    assert isolated and not any("FAIL" in line for line in isolated), r.stdout
    assert "firmware vs reference" in r.stdout


def test_trace_and_clear_errors(device, tmp_path):
    r = fuzzyctl("--port", device.pty, "--trace", "info")
    assert r.returncode == 0 and ">> +" in r.stderr and "hello seq=" in r.stderr
    r = fuzzyctl("--port", str(tmp_path / "nope"), "info")
    assert r.returncode == 2 and "does not exist" in r.stderr
    r = fuzzyctl("info")
    assert r.returncode == 2 and "--port" in r.stderr


def test_no_answer_says_what_was_sent(tmp_path):
    master, slave = os.openpty()  # a terminal nobody answers on
    try:
        r = fuzzyctl("--port", os.ttyname(slave), "--timeout", "0.1", "--retries", "1", "info")
        assert r.returncode == 2 and "no answer" in r.stderr and "hello" in r.stderr and "info" in r.stderr
    finally:
        os.close(master)
        os.close(slave)


def test_schema_mismatch_names_both_hashes(device):
    import copy

    from fuzzyctl.link.schema import Schema, load_schema
    from fuzzyctl.link.transport import Link, SchemaMismatch

    raw = copy.deepcopy(load_schema().raw)
    raw["message"][-1]["fields"][0]["max"] = 5  # another layout
    other = Schema(raw)
    with Link(device.pty, schema=other) as link:
        with pytest.raises(SchemaMismatch) as e:
            link.hello()
    assert other.hash.hex() in str(e.value) and load_schema().hash.hex() in str(e.value)


def test_corrupt_active_config_falls_back_to_backup(firmware_bin, tmp_path):
    from fuzzyctl.link.device import config_push
    from fuzzyctl.link.transport import Link

    state = tmp_path / "st"
    with Device(firmware_bin, state) as d:
        with Link(d.pty) as link:
            link.hello()
            config_push(link, b"[esr]\nwindow = 7\n")
            config_push(link, b"[esr]\nwindow = 9\n")
    (state / "config" / "active.toml").write_bytes(b"[esr]\nwindow = \x00garbage")
    with Device(firmware_bin, state) as d:
        with Link(d.pty) as link:
            info = link.hello()
        out = d.output()
    assert info["config_source"] == "backup"
    assert "active config unusable" in out and "using the backup" in out
