"""`fuzzystereo motors test`: the wiring check drives each wheel alone and says what should happen.

On the simulated motors the printed motion must match what each step says the robot should do (left
wheel forward turns it clockwise); the real backend must refuse to start without --yes and name the
missing hardware with it. (`[motors] invert_left` is the H-bridge driver's: tests/cpp/robot/test_motors.cpp.)
"""

from __future__ import annotations

import re
import subprocess

import pytest


def run(firmware_bin, *args, timeout=60):
    return subprocess.run([str(firmware_bin), *args], capture_output=True, text=True, timeout=timeout)


def _motion(stdout):
    """(forward m, turn deg) of each step, in order."""
    return [(float(a), float(b)) for a, b in re.findall(r"simulated: forward ([-+0-9.]+) m, turned ([-+0-9.]+) deg", stdout)]


@pytest.mark.firmware
def test_sequence_on_the_simulated_motors(firmware_bin):
    p = run(firmware_bin, "motors", "test", "--motors", "sim")
    assert p.returncode == 0, p.stderr
    steps = re.findall(r"^\[(\d)/5\] ([a-z ]+) \(", p.stdout, re.M)
    assert [s[1] for s in steps] == ["left wheel forward", "left wheel backward", "right wheel forward",
                                     "right wheel backward", "both wheels forward"]
    m = _motion(p.stdout)
    assert len(m) == 5
    (f_lf, t_lf), (f_lb, t_lb), (f_rf, t_rf), (f_rb, t_rb), (f_b, t_b) = m
    assert t_lf < -5 and f_lf > 0      # left forward: clockwise, and ahead
    assert t_lb > 5 and f_lb < 0       # left backward: counter-clockwise, back
    assert t_rf > 5 and f_rf > 0
    assert t_rb < -5 and f_rb < 0
    assert abs(t_b) < 0.5 and f_b > 0.05  # both: straight ahead
    assert "motors stopped" in p.stdout


@pytest.mark.firmware
@pytest.mark.parametrize("args, message", [
    (["--motors", "gpiod"], "wheels off the ground"),
    (["--duty", "0.8"], "> 0.5"),
    (["--duty", "0"], "--duty must be in (0, 1]"),
    (["--ms", "10"], "--ms must be in [50, 5000]"),
    (["--wheel", "front"], "--wheel must be sequence, left, right or both"),
])
def test_bad_options_are_one_clear_line(firmware_bin, args, message):
    p = run(firmware_bin, "motors", "test", *args)
    assert p.returncode == 2
    assert message in p.stderr and len(p.stderr.strip().splitlines()) == 1


@pytest.mark.firmware
def test_real_backend_names_the_missing_hardware(firmware_bin, tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[motors]\ngpio_chip = "gpiochip97"\n')
    p = run(firmware_bin, "motors", "test", "--motors", "gpiod", "--yes", "--config", str(cfg))
    assert p.returncode != 0
    assert "gpiochip97" in p.stderr or "libgpiod" in p.stderr
