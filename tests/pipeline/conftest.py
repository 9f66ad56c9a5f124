"""Shared simulated sessions of the pipeline tests (module-scoped, seeded)."""

from __future__ import annotations

import warnings
from collections.abc import Iterator

import pytest

from hrtls.sim.scenarios import SimulationResult, run_scenario


@pytest.fixture(autouse=True)
def _quiet() -> Iterator[None]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


@pytest.fixture(scope="session")
def office() -> SimulationResult:
    """Two minutes of office walk with cameras, beacons, tags and range nodes."""
    return run_scenario("office_random_walk", 3, duration_s=120.0)


@pytest.fixture(scope="session")
def ring() -> SimulationResult:
    """Inderst's 500 m ring corridor with all tags, seed 0."""
    return run_scenario("inderst_ring", 0)


@pytest.fixture(scope="session")
def tarrio() -> SimulationResult:
    """Tarrio's circle with 9 anchors, seed 0."""
    return run_scenario("tarrio_circle", 0)
