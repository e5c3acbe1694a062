"""The fuzzyctl command line: one-line errors, exit codes, --verbose, plots."""

from __future__ import annotations

import subprocess
import sys

from fuzzyctl.cli import main


def test_fatal_error_is_one_line_and_exit_2(tmp_path, capsys):
    rc = main(["fis", "check", "--points", "5", "--bin", str(tmp_path / "missing")])
    assert rc == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("fuzzyctl: error: firmware binary")
    assert "missing" in err and "Traceback" not in err


def test_verbose_shows_traceback(tmp_path, capsys):
    rc = main(["--verbose", "fis", "check", "--points", "5", "--bin", str(tmp_path / "missing")])
    assert rc == 2
    assert "Traceback" in capsys.readouterr().err


def test_usage_error_exit_code(capsys):
    assert main(["fis", "eval", "2", "0.5"]) == 2
    assert "not in the range" in capsys.readouterr().err


def test_fis_plot_writes_pngs(tmp_path):
    assert main(["fis", "plot", "--out", str(tmp_path), "--points", "21"]) == 0
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["fis_dc1.png", "fis_dc2.png", "fis_output.png", "fis_surface.png"]
    for p in tmp_path.iterdir():
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_fis_eval_and_show(capsys):
    assert main(["fis", "eval", "0.6", "0.6"]) == 0
    assert float(capsys.readouterr().out) == __import__("pytest").approx(3 / 7, abs=1e-6)
    assert main(["fis", "show"]) == 0
    assert "acceptable" in capsys.readouterr().out


def test_config_commands(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[esr]\nwindow = 8\n")
    assert main(["config", "check", str(bad)]) == 2
    assert "esr.window = 8 is not odd" in capsys.readouterr().err
    assert main(["config", "show"]) == 0
    assert "max_disparity = " in capsys.readouterr().out


def test_console_script_entry_point():
    proc = subprocess.run([sys.executable, "-m", "fuzzyctl", "--version"], capture_output=True, text=True)
    assert proc.returncode == 0 and "0.1.0" in proc.stdout


def test_an_output_directory_that_cannot_be_created_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory\n")
    rc = main(["fis", "plot", "--out", str(blocker / "plots")])
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("fuzzyctl: error:") and str(blocker) in err[0]
