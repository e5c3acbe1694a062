"""fuzzyctl suite-diff: pairing of closed-loop suite results, changed scenarios, sign test."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from fuzzyctl.cli import main
from fuzzyctl.errors import FatalError
from fuzzyctl.suitediff import diff, sign_test_p, to_json


def _scenario(index: int, status: str, time_s: float = 30.0, blocked: bool = False, features: str = "gap") -> dict:
    return {"index": index, "blocked": blocked, "status": status, "time_s": time_s, "features": features,
            "reached": status == "reached", "collided": status == "collision", "struck": status == "struck",
            "safe_stop": blocked and status == "blocked_stop"}


def _suite(tmp: Path, name: str, statuses: list[str], blocked: list[str], seed: int = 11) -> Path:
    sc = [_scenario(i, s, 30.0 + i) for i, s in enumerate(statuses)]
    sc += [_scenario(i, s, 40.0, blocked=True, features="ring") for i, s in enumerate(blocked)]
    p = tmp / name
    p.write_text(json.dumps({"seed": seed, "scenarios": sc}))
    return p


def test_sign_test_matches_the_binomial_tail():
    assert sign_test_p(0, 0) == 1.0
    assert sign_test_p(3, 3) == 1.0
    assert sign_test_p(5, 0) == pytest.approx(2 / 32)
    assert sign_test_p(0, 5) == pytest.approx(2 / 32)
    # 8 against 2: 2 * P(X <= 2), X ~ Bin(10, 1/2)
    assert sign_test_p(8, 2) == pytest.approx(2 * (1 + 10 + 45) / 1024)
    assert sign_test_p(1, 1) == 1.0


def test_pairs_count_gains_losses_and_list_changes(tmp_path):
    base = _suite(tmp_path, "a.json", ["reached", "timeout", "collision", "reached", "reached"], ["blocked_stop", "timeout"])
    new = _suite(tmp_path, "b.json", ["reached", "reached", "reached", "collision", "timeout"], ["timeout", "blocked_stop"])
    d = diff(base, new)
    assert (d.base.reached, d.new.reached, d.base.solvable) == (3, 3, 5)
    assert (d.base.collisions, d.new.collisions) == (1, 1)
    assert (d.gained, d.lost) == (2, 2)
    assert (d.safe_gained, d.safe_lost) == (1, 1)
    changes = {r["scenario"]: r["change"] for r in d.changed}
    assert changes == {"1": "better", "2": "better", "3": "worse", "4": "worse", "b0": "worse", "b1": "better"}
    # timeout -> collision is a change between two failures, worse
    new2 = _suite(tmp_path, "c.json", ["reached", "collision", "collision", "reached", "reached"], ["blocked_stop", "timeout"])
    d2 = diff(base, new2)
    assert [(r["scenario"], r["change"]) for r in d2.changed] == [("1", "worse")]
    assert (d2.gained, d2.lost) == (0, 0)
    j = to_json([d, d2])
    assert j["total"]["gained"] == 2 and j["total"]["lost"] == 2
    assert j["total"]["solvable"] == 10
    assert j["pairs"][0]["sign_test_p"] == 1.0


def test_contacts_have_their_own_sign_test(tmp_path):
    # base: contacts in 0 (collision), 2 (struck), b0 (collision); new: in 1 (collision) and b0 only.
    base = _suite(tmp_path, "a.json", ["collision", "reached", "struck", "reached"], ["collision", "blocked_stop"])
    new = _suite(tmp_path, "b.json", ["reached", "collision", "reached", "reached"], ["collision", "blocked_stop"])
    d = diff(base, new)
    assert (d.contacts_fewer, d.contacts_more) == (2, 1)
    j = to_json([d, d])
    assert (j["total"]["contacts_base"], j["total"]["contacts_new"]) == (6, 4)
    assert (j["total"]["contacts_fewer"], j["total"]["contacts_more"]) == (4, 2)
    assert j["total"]["contacts_sign_test_p"] == pytest.approx(sign_test_p(4, 2))
    assert j["pairs"][0]["contacts_sign_test_p"] == 1.0
    # seven scenarios that all lose their contact: p = 2 / 2^7
    many = _suite(tmp_path, "c.json", ["collision"] * 7, [])
    none = _suite(tmp_path, "d.json", ["reached"] * 7, [])
    assert to_json([diff(many, none)])["total"]["contacts_sign_test_p"] == pytest.approx(2 / 128)


def test_time_changes_only_on_request(tmp_path):
    base = _suite(tmp_path, "a.json", ["reached", "reached"], [])
    data = json.loads(base.read_text())
    data["scenarios"][1]["time_s"] += 12.0
    new = tmp_path / "b.json"
    new.write_text(json.dumps(data))
    assert diff(base, new).changed == []
    rows = diff(base, new, time_change_s=10.0).changed
    assert [(r["scenario"], r["change"]) for r in rows] == [("1", "time")]
    assert diff(base, new, time_change_s=15.0).changed == []


def test_mismatched_files_name_the_problem(tmp_path):
    base = _suite(tmp_path, "a.json", ["reached", "reached"], [])
    other_seed = _suite(tmp_path, "b.json", ["reached", "reached"], [], seed=12)
    with pytest.raises(FatalError, match="seed 12 differs"):
        diff(base, other_seed)
    fewer = _suite(tmp_path, "c.json", ["reached"], [])
    with pytest.raises(FatalError, match="only one of the two files"):
        diff(base, fewer)
    bad = tmp_path / "d.json"
    bad.write_text("{not json")
    with pytest.raises(FatalError, match="is not valid JSON"):
        diff(base, bad)
    (tmp_path / "e.json").write_text(json.dumps({"seed": 11}))
    with pytest.raises(FatalError, match="no 'scenarios' list"):
        diff(base, tmp_path / "e.json")
    with pytest.raises(FatalError, match="cannot read"):
        diff(base, tmp_path / "missing.json")


def test_cli_prints_tables_and_writes_json(tmp_path, capsys):
    base = _suite(tmp_path, "a.json", ["reached", "timeout", "reached"], ["blocked_stop"])
    new = _suite(tmp_path, "b.json", ["reached", "reached", "reached"], ["blocked_stop"])
    out = tmp_path / "d.json"
    assert main(["suite-diff", str(base), str(new), "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "2 -> 3 / 3" in text and "better" in text
    j = json.loads(out.read_text())
    assert j["pairs"][0]["gained"] == 1 and j["pairs"][0]["lost"] == 0
    assert math.isclose(j["pairs"][0]["sign_test_p"], 1.0)
    assert main(["suite-diff", str(base)]) != 0
    assert "pairs of files" in capsys.readouterr().err


def _run_record(root: Path, name: str, status: str, reached: bool, safe_stop: bool, shortest_m) -> Path:
    d = root / name
    d.mkdir(parents=True)
    run = {"scenario": name, "source": "sim", "start": [0.0, 0.0, 0.0], "goal": [3.0, 0.0], "robot_radius_m": 0.15,
           "world": {"obstacles": [{"id": 0, "shape": "circle", "radius": 0.2, "x": 1.5, "y": 0.4, "vx": 0.0, "vy": 0.0}]},
           "result": {"status": status, "reached": reached, "safe_stop": safe_stop, "time_s": 12.0, "path_m": 3.1,
                      "shortest_m": shortest_m, "min_clearance_m": 0.2}}
    (d / "run.json").write_text(json.dumps(run))
    frames = [{"frame": k, "t": 0.2 * k, "pose": [0.1 * k, 0.0, 0.0], "true_pose": [0.1 * k, 0.0, 0.0],
               "cmd": [0.3, 0.0], "tracks": []} for k in range(10)]
    (d / "frames.jsonl").write_text("\n".join(json.dumps(f) for f in frames) + "\n")
    return d


def test_suite_report_lists_runs_and_plots_failures(tmp_path, capsys):
    from fuzzyctl.runreport import write_suite_report

    rec = tmp_path / "rec"
    _run_record(rec, "suite-11-0", "reached", True, False, 3.0)
    _run_record(rec, "suite-11-1", "timeout", False, False, 3.0)
    _run_record(rec, "suite-11-2", "blocked_stop", False, True, 3.0)   # solvable: a failure
    _run_record(rec, "suite-11-b0", "blocked_stop", False, True, None)  # no path: a success
    out, n, failed = write_suite_report(rec, tmp_path / "s.html")
    assert (n, failed) == (4, 2)
    page = out.read_text()
    assert page.count("<figure") == 2
    assert "suite-11-1: timeout" in page and "suite-11-2: blocked_stop" in page
    assert page.index("suite-11-1") < page.index("suite-11-0")  # failures first
    _, _, _ = write_suite_report(rec, tmp_path / "all.html", failures_only=False)
    assert (tmp_path / "all.html").read_text().count("<figure") == 4
    assert main(["suite-report", str(rec)]) == 0
    assert "4 runs, 2 failed" in capsys.readouterr().out
    assert (rec / "suite.html").is_file()
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FatalError, match="no run records"):
        write_suite_report(empty, tmp_path / "x.html")
