"""Shared simulated sessions of the pipeline tests (module-scoped, seeded)."""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Iterator

import pytest

from hrtls.jobs.bench import calibrated_session
from hrtls.pipeline import preset
from hrtls.sim.scenarios import SimulationResult, run_scenario


def calibrated(sim: SimulationResult) -> SimulationResult:
    """The simulation with what its user brings: the step model and channel calibrated on the
    person's calibration walk (``default`` preset), as ``hrtls bench papers`` does."""
    options = {k: v for k, v in sim.options.items() if k != "calibration"}
    cal = run_scenario(sim.scenario, sim.seed, calibration=True, **options)
    return dataclasses.replace(sim, session=calibrated_session(preset("default"), sim.session,
                                                               cal))


@pytest.fixture(autouse=True)
def _quiet() -> Iterator[None]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


@pytest.fixture(scope="session")
def office() -> SimulationResult:
    """Two minutes of office walk with cameras, beacons, tags and range nodes."""
    return calibrated(run_scenario("office_random_walk", 3, duration_s=120.0))


@pytest.fixture(scope="session")
def ring() -> SimulationResult:
    """Inderst's 500 m ring corridor with all tags, seed 0."""
    return calibrated(run_scenario("inderst_ring", 0))


@pytest.fixture(scope="session")
def tarrio() -> SimulationResult:
    """Tarrio's circle with 9 anchors, seed 0."""
    return calibrated(run_scenario("tarrio_circle", 0))
