"""Shared fixtures: the repository's assets (the tests run from a checkout, against the installed package)."""

from pathlib import Path

import pytest

import servostack as ss

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture(scope="session")
def paper() -> ss.Scenario:
    return ss.Scenario.from_file(REPO / "assets/scenarios/paper_afma6.toml")
