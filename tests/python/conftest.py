"""Shared fixtures for the host tests (tests/python).

Tiers: plain unit tests run everywhere; tests needing the firmware binary take the
``firmware_bin`` fixture and skip (with the reason) when it has not been built; tests needing the
stereo datasets take ``datasets_root`` and skip when shared/datasets is absent.

Environment:
  FUZZYSTEREO_BIN       firmware binary (default <repo>/build/default/fuzzystereo)
  FUZZYSTEREO_DATASETS  datasets root (default <repo>/../shared/datasets)
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]


def pytest_configure(config):
    config.addinivalue_line("markers", "firmware: needs the fuzzystereo binary (skipped when absent)")
    config.addinivalue_line("markers", "datasets: needs shared/datasets (skipped when absent)")
    config.addinivalue_line("markers", "slow: takes more than a few seconds")
    # scikit-fuzzy 0.5 calls np.maximum(a, b, out) positionally (deprecated in NumPy 2.4)
    config.addinivalue_line("filterwarnings", "ignore:Passing more than 2 positional arguments:DeprecationWarning")


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO_ROOT


@pytest.fixture(scope="session")
def common_dir(repo_root) -> Path:
    return Path(os.environ.get("FUZZYSTEREO_COMMON", repo_root / "common"))


@pytest.fixture(scope="session")
def firmware_bin(repo_root) -> Path:
    """The firmware binary; the test is skipped with a clear message when it is not built."""
    env = os.environ.get("FUZZYSTEREO_BIN")
    path = Path(env) if env else repo_root / "build" / "default" / "fuzzystereo"
    if not path.is_file():
        how = "FUZZYSTEREO_BIN" if env else "build it with the 'default' CMake preset or set FUZZYSTEREO_BIN"
        pytest.skip(f"firmware binary {path} not found ({how})")
    return path


@pytest.fixture(scope="session")
def datasets_root(repo_root) -> Path:
    """The stereo datasets root; the test is skipped with a clear message when it is absent."""
    env = os.environ.get("FUZZYSTEREO_DATASETS")
    path = Path(env) if env else (repo_root / ".." / "shared" / "datasets").resolve()
    if not path.is_dir():
        pytest.skip(f"datasets root {path} not found (set FUZZYSTEREO_DATASETS)")
    return path


@pytest.fixture(scope="session")
def fis():
    from fuzzyctl.fis import Fis, load_definition

    return Fis(load_definition())
